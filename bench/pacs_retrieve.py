#!/usr/bin/python3
"""Retrieve timings of fvr-render from a real Orthanc on loopback: C-GET vs C-MOVE of the
140-image Philips CT series (73 MB), median of N runs, each into a fresh local store.

    /usr/bin/python3 bench/pacs_retrieve.py [--fvr-render build/app/fvr-render] [--runs 3]
        [--orthanc-nagle]

Starts /usr/sbin/Orthanc (never the Debian service) with a generated configuration on free
loopback ports and temporary storage, as the pacs tests do (tests/pacs/orthanc_server.cpp),
uploads the series over REST, and times the retrieve as fvr-render reports it on stderr
("retrieved ... (C-GET, 140 images in 0.43 s)"). --orthanc-nagle leaves Nagle's algorithm on in
Orthanc (DCMTK's default without TCP_NODELAY=1), as an untuned PACS would send.
"""
import argparse, json, os, re, socket, statistics, subprocess, sys, tempfile, time, urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "..", "shared", "data", "dicom", "ct_phantom_philips_512x512x140")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_orthanc(tmp, our_port, nagle):
    dicom, http = free_port(), free_port()
    config = {
        "Name": "fvr-bench", "StorageDirectory": tmp + "/storage", "IndexDirectory": tmp + "/storage",
        "DicomAet": "ORTHANC", "DicomPort": dicom, "HttpPort": http, "RemoteAccessAllowed": False,
        "AuthenticationEnabled": False, "DicomCheckCalledAet": True,
        "DicomModalities": {"fvr": ["FVRBENCH", "127.0.0.1", our_port]},
        "DicomAssociationCloseDelay": 0, "StorageCompression": False, "Plugins": [], "SaveJobs": False,
    }
    with open(tmp + "/config.json", "w") as f:
        json.dump(config, f)
    env = dict(os.environ)
    if not nagle:
        env["TCP_NODELAY"] = "1"
    log = open(tmp + "/orthanc.log", "w")
    proc = subprocess.Popen(["/usr/sbin/Orthanc", tmp + "/config.json"], stdout=log, stderr=log, env=env)
    for _ in range(600):
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{http}/system", timeout=1)
            return proc, dicom, http
        except OSError:
            time.sleep(0.1)
    proc.terminate()
    sys.exit("Orthanc did not start; see " + tmp + "/orthanc.log")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fvr-render", default=os.path.join(HERE, "..", "build", "app", "fvr-render"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--orthanc-nagle", action="store_true")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="fvr-pacs-bench-")
    listen = free_port()
    proc, dicom, http = start_orthanc(tmp, listen, a.orthanc_nagle)
    try:
        files = sorted(os.listdir(DATA))
        for name in files:
            with open(os.path.join(DATA, name), "rb") as f:
                urllib.request.urlopen(urllib.request.Request(
                    f"http://127.0.0.1:{http}/instances", data=f.read(), method="POST"))
        study = json.load(urllib.request.urlopen(f"http://127.0.0.1:{http}/studies?expand"))[0]
        uid = study["MainDicomTags"]["StudyInstanceUID"]
        print(f"{len(files)} instances uploaded; Orthanc Nagle {'on' if a.orthanc_nagle else 'off'}")
        for method in ("get", "move"):
            times = []
            for run in range(a.runs):
                store = f"{tmp}/store-{method}-{run}"
                r = subprocess.run([a.fvr_render, f"dicom://ORTHANC@127.0.0.1:{dicom}/{uid}",
                                    "--ae-title", "FVRBENCH", "--retrieve", method, "--listen-port",
                                    str(listen), "--store", store, "--info"],
                                   capture_output=True, text=True)
                m = re.search(r"(\d+) images in ([0-9.]+) s", r.stderr)
                if r.returncode != 0 or not m:
                    sys.exit(f"fvr-render failed ({r.returncode}): {r.stderr}")
                times.append(float(m.group(2)))
            print(f"{method:5s} {m.group(1)} images: median {statistics.median(times):.2f} s "
                  f"(runs {', '.join(f'{t:.2f}' for t in times)})")
    finally:
        proc.terminate()
        proc.wait()
        subprocess.run(["rm", "-rf", tmp])


if __name__ == "__main__":
    main()
