// core/pacs against peers that misbehave on purpose, without a PACS: echo's failure messages
// (closed port, a peer that never answers, one that hangs up, aborts, rejects or speaks TLS),
// TLS settings that name bad files, the dicom:// URL and the study date rule of queries.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <fvr/core/pacs/dicom_url.h>

#include <gtest/gtest.h>

#include "pacs_local_test_support.h"

using namespace fvr::test::pacs_local;

namespace {

/** A listening loopback socket on a free port (connections queue, nobody answers). */
struct Listening {
    Listening() {
        fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t len = sizeof addr;
        ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
        ::listen(fd, 4);
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
        port = ntohs(addr.sin_port);
    }
    ~Listening() { ::close(fd); }
    int fd = -1, port = 0;
};

Node nodeAt(int port) { return Node{"test", "PACS", "127.0.0.1", port}; }

} // namespace

TEST(DicomUrl, ParsesNodeStudyAndSeries) {
    const DicomUrl u = parseDicomUrl("dicom://ORTHANC@pacs.example.org:4242/1.2.3/1.2.3.4");
    EXPECT_EQ(u.node.calledAe, "ORTHANC");
    EXPECT_EQ(u.node.host, "pacs.example.org");
    EXPECT_EQ(u.node.port, 4242);
    EXPECT_EQ(u.studyUid, "1.2.3");
    EXPECT_EQ(u.seriesUid, "1.2.3.4");
    EXPECT_EQ(toString(u), "dicom://ORTHANC@pacs.example.org:4242/1.2.3/1.2.3.4");
    EXPECT_EQ(parseDicomUrl("DICOM://A@h").node.port, 104); // the DICOM port by default
    EXPECT_TRUE(parseDicomUrl("dicom://A@h:11112/").studyUid.empty());
}

TEST(DicomUrl, BadUrlsSayWhatIsWrong) {
    const std::pair<const char*, const char*> cases[] = {
        {"http://A@h:1", "not a dicom:// URL"},
        {"dicom://h:104", "no called AE title before '@'"},
        {"dicom://A@:104", "no host after '@'"},
        {"dicom://A@h:0", "the port \"0\" is not a number from 1 to 65535"},
        {"dicom://A@h:12x", "the port \"12x\" is not a number"},
        {"dicom://A@h:104/1.2.abc", "the study UID \"1.2.abc\" is not a DICOM UID"},
        {"dicom://A@h:104/1.2/3.x", "the series UID \"3.x\" is not a DICOM UID"},
        {"dicom://A@h:104/1.2/3.4/5", "more than a study and a series UID"},
        {"dicom://ABCDEFGHIJKLMNOPQ@h", "must have 1 to 16 characters"},
    };
    for (const auto& [url, what] : cases) {
        const std::string msg = errorOf([&] { parseDicomUrl(url); });
        EXPECT_NE(msg.find(what), std::string::npos) << url << " -> " << msg;
        EXPECT_NE(msg.find(url), std::string::npos) << msg; // names the URL
    }
}

TEST(PacsEchoFailure, ClosedPortSaysConnectionRefused) {
    int port = 0;
    {
        Listening l; // bound then closed: nothing listens there now
        port = l.port;
    }
    const std::string msg = errorOf([&] { echo(nodeAt(port), LocalAe{}); });
    EXPECT_NE(msg.find("PACS@127.0.0.1:" + std::to_string(port) +
                       ": connection refused (nothing listens at 127.0.0.1:" +
                       std::to_string(port) + ")"),
              std::string::npos)
        << msg;
}

TEST(PacsEchoFailure, SilentPeerSaysItStoppedAnswering) {
    Listening l; // the connection is queued, the association request never answered
    LocalAe local;
    local.timeoutSeconds = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const std::string msg = errorOf([&] { echo(nodeAt(l.port), local); });
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_NE(msg.find("PACS@127.0.0.1:" + std::to_string(l.port) +
                       ": the PACS stopped answering (no reply within 1 s)"),
              std::string::npos)
        << msg;
    EXPECT_LE(s, 2.0); // the timeout + 1 s
}

/** Echo against a peer that accepts, reads the association request, sends `reply` (raw PDU
 *  bytes, maybe none) and closes: the message. */
std::string echoAgainst(const std::vector<unsigned char>& reply) {
    Listening l;
    std::thread peer([&] {
        const int c = ::accept(l.fd, nullptr, nullptr);
        if (c < 0) return;
        char buf[4096];
        (void)::recv(c, buf, sizeof buf, 0);
        if (!reply.empty()) (void)::send(c, reply.data(), reply.size(), MSG_NOSIGNAL);
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        ::close(c);
    });
    const std::string msg = errorOf([&] { echo(nodeAt(l.port), LocalAe{}); });
    peer.join();
    return msg;
}

TEST(PacsEchoFailure, PeerThatHangsUpSaysSo) {
    const std::string msg = echoAgainst({});
    EXPECT_NE(msg.find("the PACS closed the connection without answering the association "
                       "request (if 127.0.0.1:"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("is a DICOM TLS port, turn TLS on for this node)"), std::string::npos)
        << msg;
    EXPECT_EQ(msg.find("AE title"), std::string::npos) << msg;
}

TEST(PacsEchoFailure, AbortAtAssociationAsksAboutOurAeTitle) {
    // A-ABORT (type 7, length 4, source 0: the service user)
    const std::string msg = echoAgainst({0x07, 0, 0, 0, 0, 4, 0, 0, 0, 0});
    EXPECT_NE(msg.find("the PACS aborted the association (is our AE title FVR known to it?)"),
              std::string::npos)
        << msg;
}

TEST(PacsEchoFailure, RejectionSaysTheReason) {
    // A-ASSOCIATE-RJ: permanent (1), by the service user (1), calling AE not recognised (3)
    std::string msg = echoAgainst({0x03, 0, 0, 0, 0, 4, 0, 1, 1, 3});
    EXPECT_NE(msg.find(": the association was rejected by the PACS: calling AE title not "
                       "recognised (permanent)"),
              std::string::npos)
        << msg;
    // transient (2), by the service provider's presentation layer (3), congestion (1)
    msg = echoAgainst({0x03, 0, 0, 0, 0, 4, 0, 2, 3, 1});
    EXPECT_NE(msg.find("rejected by the PACS: temporary congestion (transient: try again later)"),
              std::string::npos)
        << msg;
}

TEST(PacsEchoFailure, ATlsPortSaysSo) {
    // What a TLS server says to a plain association request: an alert record.
    const std::string msg = echoAgainst({0x15, 0x03, 0x03, 0x00, 0x02, 0x02, 0x32});
    EXPECT_NE(msg.find("the PACS answered in TLS: 127.0.0.1:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("is a DICOM TLS port (turn TLS on for this node)"), std::string::npos)
        << msg;
}

TEST(PacsEchoFailure, UnreadableTlsFilesAreNamed) {
    Node node = nodeAt(104);
    node.tls = true;
    LocalAe local;
    local.tls.trustedCaFiles = {"/nonexistent/ca.pem"};
    EXPECT_NE(errorOf([&] { echo(node, local); })
                  .find("the trusted CA certificate file /nonexistent/ca.pem cannot be read: No "
                        "such file or directory"),
              std::string::npos);
    const fs::path notPem = fvr::test::tmpDir() / "not-a-certificate.pem";
    std::ofstream(notPem) << "hello";
    local.tls.trustedCaFiles = {notPem.string()};
    EXPECT_NE(errorOf([&] { echo(node, local); })
                  .find("the trusted CA certificate file " + notPem.string() +
                        " is not a PEM certificate ("),
              std::string::npos);
    local.tls.certificateFile = "/nonexistent/our.pem";
    EXPECT_NE(errorOf([&] { echo(node, local); }).find("set both or neither"), std::string::npos);
    local.tls.privateKeyFile = "/nonexistent/our.key";
    EXPECT_NE(errorOf([&] { echo(node, local); })
                  .find("the TLS certificate file /nonexistent/our.pem cannot be read: No such "
                        "file or directory"),
              std::string::npos);
    local.tls = {};
    EXPECT_NE(errorOf([&] { echo(node, local); }).find("needs a trusted CA certificate file"),
              std::string::npos);
}

TEST(PacsEchoFailure, BadSettingsAreNamed) {
    LocalAe local;
    local.aeTitle = "";
    EXPECT_NE(errorOf([&] { echo(nodeAt(104), local); }).find("our AE title"), std::string::npos);
    EXPECT_NE(errorOf([&] { echo(nodeAt(70000), LocalAe{}); }).find("the PACS port 70000"),
              std::string::npos);
}

// The study date rule of the dialog, fvr-render --query and findStudies: calendar days only
// (20231301 went to the PACS as it was and matched nothing, without a word).
TEST(PacsQuery, StudyDatesAreCalendarDays) {
    const auto match = [](const std::string& from, const std::string& to) {
        StudyQuery q;
        q.dateFrom = from;
        q.dateTo = to;
        return studyDateMatch(q);
    };
    EXPECT_EQ(match("", ""), "");
    EXPECT_EQ(match("20240229", "20240229"), "20240229"); // a leap day
    EXPECT_EQ(match("20100101", ""), "20100101-");
    EXPECT_EQ(match("", "20100101"), "-20100101");
    EXPECT_EQ(match("20100101", "20101231"), "20100101-20101231");
    for (const char* bad : {"20231301", "20230229", "20230431", "20230100", "2023-01-01", "2023"})
        EXPECT_NE(
            errorOf([&] { match(bad, ""); }).find(std::string("\"") + bad + "\" is not a date"),
            std::string::npos)
            << bad;
    EXPECT_NE(errorOf([&] { match("20200102", "20200101"); }).find("ends before it begins"),
              std::string::npos);
}
