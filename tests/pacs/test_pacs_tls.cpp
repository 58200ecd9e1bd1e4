// DICOM TLS against an Orthanc with "DicomTlsEnabled": a CA, Orthanc's certificate, ours and a
// stranger's made with the openssl command. Echo, find, C-GET, C-STORE and a C-MOVE into our TLS
// listener work; an untrusted certificate either way, plain DICOM to the TLS port, TLS to a
// plain port and a key that does not match its certificate each fail with words that say so.
#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>

#include "pacs_environment.h"
#include "slow_peer.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core;
using namespace fvr::core::pacs;
using fvr::test::OrthancServer;
using fvr::test::PacsEnvironment;

namespace {

PacsEnvironment& env() { return PacsEnvironment::get(); }

std::string pacsError(const std::function<void()>& f) {
    try {
        f();
    } catch (const PacsError& e) {
        std::printf("[ message  ] %s\n", e.what()); // the words, for whoever reads the log
        std::fflush(stdout);
        return e.what();
    }
    return "";
}

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string slicerStudy() {
    return fvr::test::dicomTag(
        *fs::directory_iterator(fvr::test::sharedData() / fvr::test::kSlicer), "StudyInstanceUID");
}

/** The certificates (made once) and the TLS Orthanc every test here talks to. */
class PacsTls : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (!PacsEnvironment::get().skipReason().empty() ||
            !PacsEnvironment::get().setupError().empty())
            return;
        if (fvr::test::runCommand("openssl version >/dev/null 2>&1").status != 0) {
            s_skip = "the openssl command is not installed (apt package openssl)";
            return;
        }
        try {
            makeCertificates();
            startOrthanc();
        } catch (const std::exception& e) {
            s_error = e.what();
        }
    }
    static void TearDownTestSuite() { s_orthanc.reset(); }

    void SetUp() override {
        FVR_REQUIRE_ORTHANC();
        if (!s_skip.empty()) GTEST_SKIP() << s_skip;
        ASSERT_TRUE(s_error.empty()) << s_error;
    }

    static fs::path dir() { return env().dir / "tls"; }
    static std::string file(const char* name) { return (dir() / name).string(); }

    /** Runs an openssl command in dir(); throws with its output when it fails. */
    static void openssl(const std::string& args) {
        const auto r =
            fvr::test::runCommand("cd '" + dir().string() + "' && openssl " + args + " 2>&1");
        if (r.status != 0) throw std::runtime_error("openssl " + args + ":\n" + r.out);
    }

    /** A CA; Orthanc's and our certificates signed by it; a stranger's self-signed one; another
     *  CA that signed nothing here. RSA 2048, PEM, keys unencrypted. */
    static void makeCertificates() {
        fs::remove_all(dir());
        fs::create_directories(dir());
        for (const char* ca : {"ca", "other-ca"})
            openssl(std::string("req -x509 -newkey rsa:2048 -nodes -days 2 -keyout ") + ca +
                    ".key -out " + ca + ".pem -subj /CN=" + ca);
        for (const char* name : {"orthanc", "ours"}) {
            const std::string n = name;
            openssl("req -newkey rsa:2048 -nodes -keyout " + n + ".key -out " + n +
                    ".csr -subj /CN=" + n);
            openssl("x509 -req -days 2 -in " + n +
                    ".csr -CA ca.pem -CAkey ca.key -CAcreateserial "
                    "-out " +
                    n + ".pem");
        }
        openssl("req -x509 -newkey rsa:2048 -nodes -days 2 -keyout stranger.key -out "
                "stranger.pem -subj /CN=stranger");
    }

    /** Orthanc with DICOM TLS only, our certificate required, its modality "fvr" (us) reached
     *  over TLS at our TLS listener's port; the Slicer head uploaded. */
    static void startOrthanc() {
        s_listenPort = fvr::test::freeLoopbackPort();
        const nlohmann::json tls = {
            {"DicomTlsEnabled", true},
            {"DicomTlsCertificate", file("orthanc.pem")},
            {"DicomTlsPrivateKey", file("orthanc.key")},
            {"DicomTlsTrustedCertificates", file("ca.pem")},
            {"DicomTlsRemoteCertificateRequired", true},
            {"DicomModalities",
             {{"fvr",
               {{"AET", fvr::test::kOurAe},
                {"Host", "127.0.0.1"},
                {"Port", s_listenPort},
                {"UseDicomTls", true}}}}},
        };
        s_orthanc = std::make_unique<OrthancServer>(dir() / "orthanc", fvr::test::kOurAe,
                                                    s_listenPort, tls);
        if (s_orthanc->upload(fvr::test::sharedData() / fvr::test::kSlicer) != 93)
            throw std::runtime_error("the TLS Orthanc did not store the 93 images:\n" +
                                     s_orthanc->log());
    }

    static Node node() {
        Node n = env().node();
        n.port = s_orthanc->dicomPort();
        n.tls = true;
        return n;
    }

    static LocalAe local() {
        LocalAe l = env().local();
        l.listenPort = s_listenPort;
        l.timeoutSeconds = 5;
        l.tls.certificateFile = file("ours.pem");
        l.tls.privateKeyFile = file("ours.key");
        l.tls.trustedCaFiles = {file("ca.pem")};
        return l;
    }

    static inline std::unique_ptr<OrthancServer> s_orthanc;
    static inline int s_listenPort = 0;
    static inline std::string s_skip, s_error;
};

} // namespace

TEST_F(PacsTls, EchoFindGetAndStore) {
    EXPECT_NO_THROW(echo(node(), local()));
    const auto studies = findStudies(node(), local(), {});
    ASSERT_EQ(studies.size(), 1u);
    EXPECT_EQ(studies[0].studyUid, slicerStudy());
    LocalStore store(dir() / "store-get");
    retrieve(node(), local(), slicerStudy(), "", store);
    const auto entry = store.find(slicerStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 93);

    ProjectionImage img;
    img.width = img.height = 16;
    img.pixelSize = 1.0;
    img.pixels.assign(16 * 16, 2.0f);
    const fs::path sent = dir() / "sent.dcm";
    writeDicomProjection(sent, img, {"TLS^SEND", "TLS1", "", "FVR TLS test", "mm"});
    sendFiles(node(), local(), {sent});
    const auto lookup =
        s_orthanc->post("/tools/lookup", fvr::test::dicomTag(sent, "SOPInstanceUID"));
    EXPECT_EQ(nlohmann::json::parse(lookup.body).size(), 1u) << lookup.body;
}

TEST_F(PacsTls, MoveIntoOurTlsListener) {
    LocalAe l = local();
    l.listenTls = true;
    Node n = node();
    n.retrieve = RetrieveMethod::Move;
    LocalStore store(dir() / "store-move");
    retrieve(n, l, slicerStudy(), "", store);
    const auto entry = store.find(slicerStudy());
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 93);
}

TEST_F(PacsTls, OurListenerRefusesPlainDicom) {
    LocalAe l = local();
    l.listenTls = true;
    l.allowedPeers = {{l.aeTitle, ""}}; // our echo() below calls as our own AE title
    LocalStore store(dir() / "store-listener");
    StorageListener listener(l, store);
    listener.start();
    Node us{"us", l.aeTitle, "127.0.0.1", l.listenPort};
    const std::string plain = pacsError([&] { echo(us, l); });
    EXPECT_NE(plain.find("without answering the association request"), std::string::npos) << plain;
    us.tls = true;
    EXPECT_NO_THROW(echo(us, l)); // the same listener over TLS
}

// Our TLS listener checks its peers' certificates (the default): a client whose certificate no
// trusted CA signed, or that shows none, gets no association; with the check turned off both do.
TEST_F(PacsTls, OurTlsListenerRefusesAStrangerAndAClientWithoutCertificate) {
    LocalAe l = local();
    l.listenTls = true;
    l.allowedPeers = {{l.aeTitle, ""}}; // the clients below call as our own AE title
    const Node us{"us", l.aeTitle, "127.0.0.1", l.listenPort, RetrieveMethod::Get, true};
    LocalAe stranger = local();
    stranger.tls.certificateFile = file("stranger.pem");
    stranger.tls.privateKeyFile = file("stranger.key");
    LocalAe anonymous = local();
    anonymous.tls.certificateFile.clear();
    anonymous.tls.privateKeyFile.clear();
    for (const bool verify : {true, false}) {
        SCOPED_TRACE(verify ? "peer check on" : "peer check off");
        l.tls.verifyPeer = verify;
        LocalStore store(dir() / "store-listener-check");
        StorageListener listener(l, store);
        listener.start();
        EXPECT_NO_THROW(echo(us, local())); // signed by the CA: always in
        if (verify) {
            EXPECT_NE(pacsError([&] { echo(us, stranger); }).find("TLS"), std::string::npos);
            EXPECT_NE(pacsError([&] { echo(us, anonymous); }).find("TLS"), std::string::npos);
        } else {
            EXPECT_NO_THROW(echo(us, stranger));
            EXPECT_NO_THROW(echo(us, anonymous));
        }
    }
}

// The TLS listener: a peer that reaches the port and sends its TLS handshake one byte a second
// (each within the timeout, so OpenSSL's every read succeeds) is dropped at the timeout of the
// connection, and the listener serves the next peer.
TEST_F(PacsTls, ADrippedTlsHandshakeIsDroppedAtTheTimeout) {
    LocalAe l = local();
    l.listenTls = true;
    l.timeoutSeconds = 3;
    l.allowedPeers = {{l.aeTitle, ""}};
    LocalStore store(dir() / "store-drip");
    StorageListener listener(l, store);
    listener.start();
    // A TLS record (handshake, TLS 1.0 record version) with 200 bytes to follow.
    const double droppedAfter =
        fvr::test::dripUntilDropped(l.listenPort, {0x16, 0x03, 0x01, 0x00, 0xc8}, 0x01);
    std::printf("[ timing   ] dripped TLS handshake dropped after %.2f s (timeout %d s)\n",
                droppedAfter, l.timeoutSeconds);
    ASSERT_GE(droppedAfter, 0) << "the TLS listener still held the dripping peer after 30 s";
    EXPECT_LE(droppedAfter, l.timeoutSeconds + 1.0);
    Node us{"us", l.aeTitle, "127.0.0.1", l.listenPort};
    us.tls = true;
    EXPECT_NO_THROW(echo(us, l));
}

TEST_F(PacsTls, AStrangersCertificateIsRefused) {
    LocalAe l = local();
    l.tls.certificateFile = file("stranger.pem");
    l.tls.privateKeyFile = file("stranger.key");
    const std::string msg = pacsError([&] { echo(node(), l); });
    EXPECT_NE(msg.find("TLS"), std::string::npos) << msg;
    EXPECT_NE(msg.find("accept our certificate " + file("stranger.pem")), std::string::npos) << msg;
}

TEST_F(PacsTls, APacsCertificateWeDoNotTrustIsRefused) {
    LocalAe l = local();
    l.tls.trustedCaFiles = {file("other-ca.pem")};
    const std::string msg = pacsError([&] { echo(node(), l); });
    EXPECT_NE(msg.find("TLS handshake with ORTHANC@127.0.0.1:" + std::to_string(node().port) +
                       " failed: certificate verify failed (the PACS's certificate is not "
                       "signed by a CA we trust)"),
              std::string::npos)
        << msg;
}

TEST_F(PacsTls, PlainDicomToTheTlsPortSaysSo) {
    Node n = node();
    n.tls = false;
    const std::string msg = pacsError([&] { echo(n, local()); });
    EXPECT_NE(msg.find("turn TLS on for this node"), std::string::npos) << msg;
}

TEST_F(PacsTls, TlsToAPlainPortSaysSo) {
    Node n = env().node(); // the plain Orthanc
    n.tls = true;
    const std::string msg = pacsError([&] { echo(n, local()); });
    EXPECT_NE(msg.find("TLS handshake with ORTHANC@"), std::string::npos) << msg;
    EXPECT_NE(msg.find("a DICOM TLS port?"), std::string::npos) << msg;
}

TEST_F(PacsTls, AKeyThatIsNotTheCertificatesIsNamed) {
    LocalAe l = local();
    l.tls.privateKeyFile = file("stranger.key");
    const std::string msg = pacsError([&] { echo(node(), l); });
    EXPECT_NE(msg.find("the TLS private key file " + file("stranger.key") +
                       " does not match the certificate " + file("ours.pem")),
              std::string::npos)
        << msg;
}

TEST_F(PacsTls, AFrozenTlsPacsStopsAnsweringWithinTheTimeout) {
    LocalAe l = local();
    l.timeoutSeconds = 2;
    struct Thaw {
        ~Thaw() { s_orthanc->cont(); }
    } thaw;
    using Clock = std::chrono::steady_clock;
    s_orthanc->stop(); // before: the TLS handshake waits
    auto at = Clock::now();
    std::string msg = pacsError([&] { echo(node(), l); });
    double s = std::chrono::duration<double>(Clock::now() - at).count();
    std::printf("[ timing   ] TLS C-ECHO, frozen before: %.2f s\n", s);
    EXPECT_NE(msg.find("the PACS stopped answering (no reply within 2 s)"), std::string::npos)
        << msg;
    EXPECT_LE(s, 3.0);
    s_orthanc->cont();
    LocalStore store(dir() / "store-frozen");
    bool frozen = false;
    msg = pacsError([&] {
        retrieve(node(), l, slicerStudy(), "", store, [&](const RetrieveProgress& p) {
            if (!frozen && p.received >= 10) {
                s_orthanc->stop(); // mid-transfer: a TLS read waits
                at = Clock::now();
                frozen = true;
            }
        });
    });
    s = std::chrono::duration<double>(Clock::now() - at).count();
    std::printf("[ timing   ] TLS C-GET, frozen at 10 images: %.2f s\n", s);
    EXPECT_TRUE(frozen);
    EXPECT_NE(msg.find("the PACS stopped answering (no reply within 2 s)"), std::string::npos)
        << msg;
    EXPECT_LE(s, 3.0);
}

TEST_F(PacsTls, FvrRenderQueryAndMoveOverTls) {
    const std::string url = "dicom://ORTHANC@127.0.0.1:" + std::to_string(node().port);
    const std::string tls = " --ae-title " + std::string(fvr::test::kOurAe) + " --tls --tls-cert " +
                            file("ours.pem") + " --tls-key " + file("ours.key") + " --tls-ca " +
                            file("ca.pem");
    const fs::path err = dir() / "cli.err";
    auto r = fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + url +
                                   " --query PatientName=Austrialian" + tls + " 2>" + err.string());
    ASSERT_EQ(r.status, 0) << r.out << readAll(err);
    const auto studies = nlohmann::json::parse(r.out);
    ASSERT_EQ(studies.size(), 1u) << r.out;
    EXPECT_EQ(studies[0]["studyUid"], slicerStudy());
    // C-MOVE into fvr-render's own TLS listener, then --info on the retrieved study.
    r = fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + url + "/" + slicerStudy() + tls +
                              " --retrieve move --listen-port " + std::to_string(s_listenPort) +
                              " --store " + (dir() / "cli-store").string() + " --info 2>" +
                              err.string());
    ASSERT_EQ(r.status, 0) << r.out << readAll(err);
    const auto info = nlohmann::json::parse(r.out);
    ASSERT_EQ(info["series"].size(), 1u) << r.out;
    EXPECT_EQ(info["series"][0]["dims"], nlohmann::json({64, 64, 93})) << r.out;
    // Without our certificate's key: the option named, fvr-render fails before any network.
    r = fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + url + " --query PatientName=*" +
                              " --tls --tls-cert " + file("ours.pem") + " --tls-ca " +
                              file("ca.pem") + " 2>" + err.string());
    EXPECT_NE(r.status, 0);
    EXPECT_NE(readAll(err).find("set both or neither"), std::string::npos) << readAll(err);
}
