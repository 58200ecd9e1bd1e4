#pragma once
// A real Orthanc (the Debian package's /usr/sbin/Orthanc, not its service) for the PACS tests:
// started with a generated configuration on free loopback ports with temporary storage, asked
// over its REST API (a small HTTP/1.0 client on a socket), stopped at the end.
#include <filesystem>
#include <string>

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
     *  waits until GET /system answers. Throws std::runtime_error with Orthanc's log. */
    OrthancServer(const std::filesystem::path& dir, const std::string& ourAe, int ourPort);
    ~OrthancServer(); ///< SIGTERM, wait
    OrthancServer(const OrthancServer&) = delete;
    OrthancServer& operator=(const OrthancServer&) = delete;

    int dicomPort() const { return m_dicomPort; }
    int httpPort() const { return m_httpPort; }
    std::string log() const;

    HttpResponse get(const std::string& path) const;
    HttpResponse post(const std::string& path, const std::string& body) const;
    /** POST /instances for each file; returns how many Orthanc stored. */
    int upload(const std::filesystem::path& folder) const;

private:
    HttpResponse request(const std::string& method, const std::string& path,
                         const std::string& body) const;

    std::filesystem::path m_dir;
    int m_dicomPort = 0, m_httpPort = 0;
    int m_pid = -1;
};

} // namespace fvr::test
