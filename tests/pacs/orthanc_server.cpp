#include "orthanc_server.h"

#include <arpa/inet.h>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <netinet/in.h>
#include <sstream>
#include <stdexcept>
#include <sys/socket.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;

namespace fvr::test {
namespace {

std::string readFile(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

int connectLoopback(int port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return fd;
    if (fd >= 0) ::close(fd);
    return -1;
}

bool sendAll(int fd, const std::string& data) {
    std::size_t sent = 0;
    while (sent < data.size()) {
        const ssize_t n = ::send(fd, data.data() + sent, data.size() - sent, MSG_NOSIGNAL);
        if (n <= 0) return false;
        sent += static_cast<std::size_t>(n);
    }
    return true;
}

} // namespace

int freeLoopbackPort() {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof addr;
    if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0)
        throw std::runtime_error("cannot find a free loopback port");
    ::close(fd);
    return ntohs(addr.sin_port);
}

fs::path OrthancServer::executable() {
    if (const char* env = std::getenv("FVR_ORTHANC"); env && *env)
        return fs::exists(env) ? fs::path(env) : fs::path();
    if (fs::exists("/usr/sbin/Orthanc")) return "/usr/sbin/Orthanc";
    if (const char* path = std::getenv("PATH")) {
        std::istringstream dirs(path);
        for (std::string dir; std::getline(dirs, dir, ':');)
            if (!dir.empty() && fs::exists(fs::path(dir) / "Orthanc"))
                return fs::path(dir) / "Orthanc";
    }
    return {};
}

OrthancServer::OrthancServer(const fs::path& dir, const std::string& ourAe, int ourPort,
                             const nlohmann::json& extra)
    : m_dir(dir), m_dicomPort(freeLoopbackPort()), m_httpPort(freeLoopbackPort()) {
    fs::remove_all(dir);
    fs::create_directories(dir / "storage");
    nlohmann::json config = {
        {"Name", "fvr-test"},
        {"StorageDirectory", (dir / "storage").string()},
        {"IndexDirectory", (dir / "storage").string()},
        {"DicomAet", kAeTitle},
        {"DicomPort", m_dicomPort},
        {"HttpPort", m_httpPort},
        {"RemoteAccessAllowed", false},
        {"AuthenticationEnabled", false},
        {"DicomCheckCalledAet", true},
        {"DicomAlwaysAllowEcho", false},
        {"DicomAlwaysAllowStore", false},
        {"DicomAlwaysAllowFind", false},
        {"DicomAlwaysAllowGet", false},
        {"DicomAlwaysAllowMove", false},
        {"DicomModalities", {{"fvr", {ourAe, "127.0.0.1", ourPort}}}},
        {"DicomAssociationCloseDelay", 0},
        {"DicomScuTimeout", 10},
        {"StorageCompression", false},
        {"Plugins", nlohmann::json::array()},
        {"SaveJobs", false},
        {"HttpDescribeErrors", true},
    };
    config.merge_patch(extra);
    std::ofstream(dir / "config.json") << config.dump(2);
    launch();
}

void OrthancServer::launch() {
    const fs::path exe = executable();
    const std::string logPath = (m_dir / "orthanc.log").string();
    std::fflush(nullptr); // the child's freopen would flush our buffered output a second time
    m_pid = ::fork();
    if (m_pid == 0) {
        std::freopen(logPath.c_str(), "a", stdout); // a restart appends
        std::freopen(logPath.c_str(), "a", stderr);
        // Orthanc's DCMTK as ours (core/src/pacs): Nagle's algorithm off, or each C-STORE it
        // sends waits for a delayed ACK.
        ::setenv("TCP_NODELAY", "1", 1);
        ::execl(exe.c_str(), exe.c_str(), (m_dir / "config.json").c_str(), nullptr);
        std::_Exit(127);
    }
    if (m_pid < 0) throw std::runtime_error("cannot fork to start Orthanc");
    // Startup, not a test's speed: generous (a loaded CI machine), ends with Orthanc's log.
    for (int i = 0; i < 600; ++i) {
        if (get("/system").status == 200) return;
        int st = 0;
        if (::waitpid(m_pid, &st, WNOHANG) == m_pid) {
            m_pid = -1;
            throw std::runtime_error("Orthanc exited at start:\n" + log());
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    throw std::runtime_error("Orthanc did not answer GET /system within 60 s:\n" + log());
}

OrthancServer::~OrthancServer() {
    if (m_pid > 0) {
        ::kill(m_pid, SIGCONT); // a frozen one would not see SIGTERM
        ::kill(m_pid, SIGTERM);
        int st = 0;
        ::waitpid(m_pid, &st, 0);
    }
    std::error_code ec;
    fs::remove_all(m_dir / "storage", ec);
}

namespace {

/** Whether every thread of `pid` is stopped ('T' in /proc/PID/task/TID/stat). */
bool allThreadsStopped(int pid) {
    std::error_code ec;
    const fs::path tasks = fs::path("/proc") / std::to_string(pid) / "task";
    bool any = false;
    for (fs::directory_iterator it(tasks, ec), end; !ec && it != end; it.increment(ec)) {
        std::ifstream in(it->path() / "stat");
        std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const auto paren = stat.rfind(')'); // the name may hold spaces; the state follows it
        if (paren == std::string::npos || paren + 2 >= stat.size()) continue;
        const char state = stat[paren + 2];
        if (state != 'T' && state != 't') return false;
        any = true;
    }
    return any;
}

} // namespace

void OrthancServer::stop() const {
    if (m_pid <= 0) return;
    // SIGSTOP takes effect as each thread next enters the kernel: until then a thread running on
    // another core may still answer. Return only once all of them are stopped.
    ::kill(m_pid, SIGSTOP);
    for (int i = 0; i < 2000 && !allThreadsStopped(m_pid); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void OrthancServer::cont() const {
    if (m_pid > 0) ::kill(m_pid, SIGCONT);
}

void OrthancServer::kill() {
    if (m_pid <= 0) return;
    ::kill(m_pid, SIGKILL);
    int st = 0;
    ::waitpid(m_pid, &st, 0);
    m_pid = -1;
}

void OrthancServer::restart() {
    kill();
    launch();
}

std::string OrthancServer::log() const { return readFile(m_dir / "orthanc.log"); }

int OrthancServer::imagesSentByGet() const {
    if (put("/tools/log-level", "verbose").status != 200) return -1;
    const std::string text = log();
    const std::string line = "(dicom) Store SCU RQ: MsgID";
    int n = 0;
    for (auto at = text.find(line); at != std::string::npos; at = text.find(line, at + 1)) ++n;
    return n;
}

HttpResponse OrthancServer::request(const std::string& method, const std::string& path,
                                    const std::string& body) const {
    HttpResponse r;
    const int fd = connectLoopback(m_httpPort);
    if (fd < 0) return r;
    std::string req = method + " " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n";
    if (method == "POST" || method == "PUT")
        req += "Content-Length: " + std::to_string(body.size()) + "\r\n";
    req += "Connection: close\r\n\r\n";
    std::string raw;
    if (sendAll(fd, req) && sendAll(fd, body)) {
        char buf[65536];
        ssize_t n;
        while ((n = ::recv(fd, buf, sizeof buf, 0)) > 0)
            raw.append(buf, static_cast<std::size_t>(n));
    }
    ::close(fd);
    const auto headerEnd = raw.find("\r\n\r\n");
    if (raw.rfind("HTTP/", 0) != 0 || headerEnd == std::string::npos) return r;
    r.status = std::atoi(raw.c_str() + raw.find(' ') + 1);
    r.body = raw.substr(headerEnd + 4);
    return r;
}

HttpResponse OrthancServer::get(const std::string& path) const { return request("GET", path, ""); }

HttpResponse OrthancServer::post(const std::string& path, const std::string& body) const {
    return request("POST", path, body);
}

HttpResponse OrthancServer::put(const std::string& path, const std::string& body) const {
    return request("PUT", path, body);
}

HttpResponse OrthancServer::remove(const std::string& path) const {
    return request("DELETE", path, "");
}

std::string OrthancServer::lookup(const std::string& uid) const {
    const HttpResponse r = post("/tools/lookup", uid);
    if (r.status != 200) return "";
    const nlohmann::json ids = nlohmann::json::parse(r.body, nullptr, false);
    return ids.is_array() && ids.size() == 1 ? ids[0].value("ID", "") : "";
}

int OrthancServer::upload(const fs::path& folder) const {
    int stored = 0;
    for (const auto& entry : fs::directory_iterator(folder))
        if (entry.is_regular_file() && post("/instances", readFile(entry.path())).status == 200)
            ++stored;
    return stored;
}

} // namespace fvr::test
