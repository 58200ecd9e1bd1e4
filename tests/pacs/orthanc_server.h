#pragma once
// A real Orthanc (the Debian package's /usr/sbin/Orthanc, not its service) for the PACS tests:
// started with a generated configuration on free loopback ports with temporary storage, asked
// over its REST API (a small HTTP/1.0 client on a socket), stopped at the end.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace fvr::test {

/** One free TCP port on 127.0.0.1 (bound to port 0, read back, closed). */
int freeLoopbackPort();

struct HttpResponse {
    int status = 0;
    std::string body;
};

class OrthancServer {
public:
    static constexpr const char* kAeTitle = "ORTHANC";
    /** Orthanc's executable ($FVR_ORTHANC, else /usr/sbin/Orthanc, else on PATH); empty when
     *  there is none. */
    static std::filesystem::path executable();

    /** Writes the configuration into `dir` (storage and index below it): DICOM and HTTP ports
     *  free on 127.0.0.1, AE title ORTHANC, called AE checked, only known modalities allowed,
     *  and one modality: `ourAe` at 127.0.0.1:`ourPort` (our listener). Starts Orthanc and
     *  waits until GET /system answers. Throws std::runtime_error with Orthanc's log. `extra`:
     *  settings merged over these (DICOM TLS, a modality entry with "UseDicomTls"). */
    OrthancServer(const std::filesystem::path& dir, const std::string& ourAe, int ourPort,
                  const nlohmann::json& extra = nlohmann::json::object());
    ~OrthancServer(); ///< SIGTERM, wait
    OrthancServer(const OrthancServer&) = delete;
    OrthancServer& operator=(const OrthancServer&) = delete;

    int dicomPort() const { return m_dicomPort; }
    int httpPort() const { return m_httpPort; }
    std::string log() const;

    // Faults for the timeout tests: the process frozen (SIGSTOP: its sockets stay open, nothing
    // answers), thawed (SIGCONT), killed (SIGKILL: the kernel closes its connections), started
    // again on the same ports and storage (restart(), after kill()).
    void stop() const;
    void cont() const;
    void kill();
    void restart();

    HttpResponse get(const std::string& path) const;
    HttpResponse post(const std::string& path, const std::string& body) const;
    HttpResponse put(const std::string& path, const std::string& body) const;
    HttpResponse remove(const std::string& path) const; ///< DELETE
    /** Orthanc's ID of the resource with DICOM UID `uid` (POST /tools/lookup), "" if none. */
    std::string lookup(const std::string& uid) const;
    /** POST /instances for each file; returns how many Orthanc stored. */
    int upload(const std::filesystem::path& folder) const;
    /** Orthanc's own count of the images it sent by C-GET: the C-STORE sub-operations its C-GET
     *  SCP wrote in its log ("Store SCU RQ", one per instance sent). Orthanc logs them only at
     *  its verbose level, which the first call sets (PUT /tools/log-level), so a first call
     *  before the retrieves returns 0; -1 when the level cannot be set. No statistic of its REST
     *  API counts what it sends. */
    int imagesSentByGet() const;

private:
    void launch();
    HttpResponse request(const std::string& method, const std::string& path,
                         const std::string& body) const;

    std::filesystem::path m_dir;
    int m_dicomPort = 0, m_httpPort = 0;
    int m_pid = -1;
};

} // namespace fvr::test
