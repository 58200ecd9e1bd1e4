#!/usr/bin/env python3
"""Checks the fvr-render commands that README.md and docs/**/*.md show (ctest docs.Examples).

Every `fvr-render ...` command, in a fenced code block or an inline code span, is checked:
each --option it names must appear in the built binary's `fvr-render --help`, so a doc cannot
show an option that does not exist (or no longer exists).

The commands in fenced code blocks whose INPUT is a built-in phantom (`phantom:...`) are cheap
and need nothing the user lacks, so they are also run: every output option (--out,
--material-out) is rewritten into a temporary folder, and the command must exit with status 0
and write its output. Commands that name files the reader must supply (a DICOM folder, a
`--views FILE`), talk to a PACS (`dicom://`, --send) or benchmark (--bench) are only checked.

With --python, the ```python blocks of each file run too, one file's blocks in order as one
script (a later block may use what an earlier one defined), in a temporary folder.

The relative links of those files (to files and to #headings) must resolve too.

Usage: check_examples.py --fvr-render PATH --root REPO --tmp DIR [--list]
                         [--python EXE --pythonpath DIR]
Exit status: 0 when every command passes, 1 otherwise (each failure names the file and line).
"""
import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

OPTION = re.compile(r"(?<![\w-])--[a-z0-9][a-z0-9-]*")
FENCE = re.compile(r"^\s*(```|~~~)")
# A line that runs fvr-render: optional VAR=value words, then fvr-render or a path ending in it.
COMMAND = re.compile(r"^\s*(?:[A-Za-z_][A-Za-z0-9_]*=\S*\s+)*(?:\S*/)?fvr-render(?=\s|$)")
# Options whose value is a file the command writes (rewritten into the temporary folder).
OUTPUT_OPTIONS = ("--out", "--material-out")
# What keeps a fenced command from being run (it needs something a reader supplies or a network).
NOT_RUN = ("dicom://", "--send", "--bench", "--views", "--query")


class Example:
    def __init__(self, path: Path, line: int, text: str, fenced: bool):
        self.path, self.line, self.text, self.fenced = path, line, text, fenced

    def where(self, root: Path) -> str:
        return f"{self.path.relative_to(root)}:{self.line}"


def doc_files(root: Path) -> list:
    files = [root / "README.md"]
    files += sorted((root / "docs").rglob("*.md"))
    return [f for f in files if f.is_file()]


def fenced_examples(path: Path, lines: list) -> list:
    """fvr-render commands in fenced code blocks, continuation lines (trailing \\) joined."""
    found, inside, i = [], False, 0
    while i < len(lines):
        line = lines[i]
        if FENCE.match(line):
            inside = not inside
            i += 1
            continue
        if inside and COMMAND.match(line):
            start, text = i + 1, line
            while text.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                text = text.rstrip()[:-1] + " " + lines[i].strip()
            found.append(Example(path, start, text.strip(), True))
        i += 1
    return found


def inline_examples(path: Path, lines: list) -> list:
    """fvr-render commands in inline code spans of the prose (outside fenced blocks); a span may
    run over a line break."""
    prose, inside = [], False
    for n, line in enumerate(lines, 1):
        if FENCE.match(line):
            inside = not inside
            prose.append((n, ""))
            continue
        prose.append((n, "" if inside else line))
    text = "\n".join(line for _, line in prose)
    found = []
    for m in re.finditer(r"`([^`]+)`", text):
        span = " ".join(m.group(1).split())
        if re.match(r"(?:\S*/)?fvr-render\s", span):
            found.append(Example(path, text.count("\n", 0, m.start()) + 1, span, False))
    return found


def anchors(path: Path) -> set:
    """The heading anchors of a Markdown file, as GitHub makes them."""
    found, inside = set(), False
    for line in path.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line):
            inside = not inside
        elif not inside and line.startswith("#"):
            title = line.lstrip("#").strip().lower()
            found.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return found


def broken_links(path: Path, root: Path) -> list:
    """Relative links and images of a Markdown file whose file or #anchor does not exist."""
    # Fenced blocks blanked line for line, so that the line numbers stay right.
    text = re.sub(r"```.*?```", lambda m: "\n" * m.group(0).count("\n"),
                  path.read_text(encoding="utf-8"), flags=re.S)
    bad = []
    for m in re.finditer(r"!?\[[^\]]*\]\(([^)\s]+)\)", text):
        target = m.group(1)
        if re.match(r"[a-z]+:", target):
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        line = text.count("\n", 0, m.start()) + 1
        if not dest.exists():
            bad.append(f"{path.relative_to(root)}:{line}: link to {target}: no file {file}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{path.relative_to(root)}:{line}: link to {target}: no heading #{anchor}")
    return bad


def help_options(fvr_render: str) -> set:
    out = subprocess.run([fvr_render, "--help"], capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        sys.exit(f"{fvr_render} --help: exit status {out.returncode}\n{out.stderr}")
    return set(OPTION.findall(out.stdout))


def command_words(text: str) -> list:
    """The command's words, the shell comment and the words before fvr-render removed."""
    words = shlex.split(text, comments=True)
    while words and not words[0].endswith("fvr-render"):
        words.pop(0)
    return words[1:]


def runnable(ex: Example) -> bool:
    if not ex.fenced or any(s in ex.text for s in NOT_RUN):
        return False
    try:
        words = command_words(ex.text)
    except ValueError:
        return False
    return bool(words) and words[0].startswith("phantom:")


def run_example(ex: Example, fvr_render: str, tmp: Path, index: int) -> str:
    """Runs the command with its outputs in a folder of its own; '' on success, else why not."""
    folder = tmp / f"example_{index:03d}"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    words, outputs, args = command_words(ex.text), [], []
    i = 0
    while i < len(words):
        w = words[i]
        name, eq, value = w.partition("=")
        if name in OUTPUT_OPTIONS and eq:
            outputs.append(folder / Path(value).name)
            args.append(f"{name}={outputs[-1]}")
        elif w in OUTPUT_OPTIONS and i + 1 < len(words):
            outputs.append(folder / Path(words[i + 1]).name)
            args += [w, str(outputs[-1])]
            i += 1
        else:
            args.append(w)
        i += 1
    env = dict(os.environ, FVR_FFTW_WISDOM=str(tmp / "fftwf-wisdom"))
    try:
        out = subprocess.run([fvr_render] + args, capture_output=True, text=True, timeout=600,
                             cwd=folder, env=env)
    except subprocess.TimeoutExpired:
        return "did not finish within 600 s"
    if out.returncode != 0:
        return f"exit status {out.returncode}: {out.stderr.strip()[-600:]}"
    if "--info" not in words and "--gpu-info" not in words:
        for o in outputs:
            if not o.exists() and not list(folder.glob(o.stem + "_*" + o.suffix)):
                return f"wrote no {o.name}"
    return ""


def python_scripts(files: list) -> list:
    """(file, the file's ```python blocks joined) for each file that has some."""
    scripts = []
    for f in files:
        blocks = re.findall(r"^```python\n(.*?)^```", f.read_text(encoding="utf-8"), re.S | re.M)
        if blocks:
            scripts.append((f, "\n".join(blocks)))
    return scripts


def run_python(path: Path, code: str, python: str, pythonpath: str, folder: Path) -> str:
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    (folder / "example.py").write_text(code, encoding="utf-8")
    env = dict(os.environ, PYTHONPATH=pythonpath, PYTHONDONTWRITEBYTECODE="1")
    try:
        out = subprocess.run([python, "example.py"], capture_output=True, text=True, timeout=600,
                             cwd=folder, env=env)
    except subprocess.TimeoutExpired:
        return "did not finish within 600 s"
    return "" if out.returncode == 0 else f"exit status {out.returncode}: {out.stderr.strip()[-800:]}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fvr-render", required=True)
    ap.add_argument("--root", required=True, type=Path)
    ap.add_argument("--tmp", required=True, type=Path)
    ap.add_argument("--list", action="store_true", help="list the commands, run nothing")
    ap.add_argument("--python", help="run the ```python blocks with this interpreter")
    ap.add_argument("--pythonpath", default="", help="PYTHONPATH for them (the module fvr)")
    a = ap.parse_args()
    root = a.root.resolve()
    a.fvr_render = str(Path(a.fvr_render).resolve())
    a.tmp = a.tmp.resolve()

    examples = []
    for f in doc_files(root):
        lines = f.read_text(encoding="utf-8").splitlines()
        examples += fenced_examples(f, lines) + inline_examples(f, lines)
    if not examples:
        print("no fvr-render command found in README.md or docs/", file=sys.stderr)
        return 1
    if a.list:
        for ex in examples:
            tag = "run  " if runnable(ex) else "check"
            print(f"{tag} {ex.where(root)}: {ex.text}")
        return 0

    known = help_options(a.fvr_render)
    failures, ran = [], 0
    for f in doc_files(root):
        failures += broken_links(f, root)
    for ex in examples:
        unknown = sorted(set(OPTION.findall(ex.text)) - known)
        if unknown:
            failures.append(f"{ex.where(root)}: {', '.join(unknown)} not in `fvr-render --help`"
                            f" (in: {ex.text})")
    a.tmp.mkdir(parents=True, exist_ok=True)
    for i, ex in enumerate(e for e in examples if runnable(e)):
        if any(f.startswith(ex.where(root) + ":") for f in failures):
            continue
        why = run_example(ex, a.fvr_render, a.tmp, i)
        ran += 1
        print(f"{'FAILED' if why else 'ok    '} {ex.where(root)}: {ex.text}")
        if why:
            failures.append(f"{ex.where(root)}: {why} (in: {ex.text})")
    pythons = python_scripts(doc_files(root)) if a.python else []
    for i, (f, code) in enumerate(pythons):
        why = run_python(f, code, a.python, a.pythonpath, a.tmp / f"python_{i:02d}")
        print(f"{'FAILED' if why else 'ok    '} {f.relative_to(root)}: its python blocks")
        if why:
            failures.append(f"{f.relative_to(root)}: python blocks: {why}")
    print(f"{len(examples)} fvr-render commands checked against --help, {ran} run; "
          f"{len(pythons)} files' python blocks run")
    for f in failures:
        print("FAIL " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
