// core/pacs without a PACS: the dicom:// URL, the local store and its index (strict UIDs,
// quarantine, the Incoming area, concurrent writers), echo's failure messages against sockets
// that misbehave on purpose (closed port, a peer that never answers, one that hangs up, aborts,
// rejects or speaks TLS), and TLS settings that name bad files.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/pacs/dicom_url.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>

#include "pacs/pacs_internal.h" // detail::storeDataset: what the listener and C-GET call
#include "test_support.h"

namespace fs = std::filesystem;
using namespace fvr::core::pacs;
using fvr::core::temporaryPathFor;

namespace {

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const PacsError& e) {
        return e.what();
    }
    return "";
}

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

StudyRecord study(const std::string& uid) {
    StudyRecord s;
    s.studyUid = uid;
    s.patientName = "DOE^JANE";
    return s;
}

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

TEST(PacsLocalStore, IndexListsPartialThenCompleteAndSurvivesANewObject) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-unit";
    fs::remove_all(root);
    {
        LocalStore store(root);
        EXPECT_TRUE(store.studies().empty());
        store.beginRetrieve(study("1.2.3"), "");
        const SeriesRecord series{"1.2.3.1", "CT", "head", 1, 2};
        const fs::path a = store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "DICM-a").path;
        EXPECT_EQ(a, root / "1.2.3" / "1.2.3.1" / "1.2.3.1.1.dcm");
        auto entry = store.find("1.2.3");
        ASSERT_TRUE(entry);
        EXPECT_FALSE(entry->complete); // a retrieve runs: partial
        EXPECT_EQ(entry->instances, 1);
        store.storeInstance(study("1.2.3"), series, "1.2.3.1.2", "DICM-b");
        store.finishRetrieve("1.2.3", "", true);
        EXPECT_EQ(store.instancesStored(), 2);
    }
    LocalStore again(root); // the index on disk, read by a new object
    const auto entries = again.studies();
    ASSERT_EQ(entries.size(), 1u);
    EXPECT_TRUE(entries[0].complete);
    EXPECT_EQ(entries[0].instances, 2);
    EXPECT_EQ(entries[0].study.patientName, "DOE^JANE");
    ASSERT_EQ(entries[0].series.size(), 1u);
    EXPECT_TRUE(entries[0].series[0].complete);
    EXPECT_EQ(entries[0].series[0].modality, "CT");
    again.remove("1.2.3");
    EXPECT_TRUE(again.studies().empty());
    EXPECT_FALSE(fs::exists(root / "1.2.3"));
}

TEST(PacsLocalStore, AFailedRetrieveStaysPartialEvenWhenTheListenerSeesARelease) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-partial";
    fs::remove_all(root);
    LocalStore store(root);
    store.beginRetrieve(study("9.8"), "");
    store.storeInstance(study("9.8"), {"9.8.1", "MR", "", 1, 1}, "9.8.1.1", "x");
    store.finishRetrieve("9.8", "", false); // cancelled
    store.markReceived("9.8", {"9.8.1"}); // a late sub-association ends normally
    const auto entry = store.find("9.8");
    ASSERT_TRUE(entry);
    EXPECT_FALSE(entry->complete);
    EXPECT_FALSE(entry->series[0].complete);
}

TEST(PacsLocalStore, BadIndexAndBadUidsAreNamed) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-bad";
    fs::remove_all(root);
    fs::create_directories(root);
    std::ofstream(root / "index.json") << "{ not json";
    LocalStore store(root);
    const std::string msg = errorOf([&] { store.studies(); });
    EXPECT_NE(msg.find((root / "index.json").string() + " cannot be read"), std::string::npos)
        << msg;
    EXPECT_NE(errorOf([&] { store.studyFolder("../etc"); }).find("cannot name a file"),
              std::string::npos);
}

// An index edited by hand: valid JSON of the wrong shape is named like unreadable JSON (it
// was a bare json type_error without the file's name).
TEST(PacsLocalStore, AnIndexOfTheWrongShapeIsNamed) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-shape";
    for (const char* text :
         {"", "{\"studies\": {\"1.2.3\": {\"patientName\": \"DOE^J", "[1, 2]", "{\"studies\": 5}",
          "{\"studies\": {\"1.2.3\": 5}}", "{\"studies\": {\"1.2.3\": {\"patientName\": 5}}}",
          "{\"studies\": {\"1.2.3\": {\"complete\": \"yes\"}}}",
          "{\"studies\": {\"1.2.3\": {\"series\": {\"1.2.4\": []}}}}",
          "{\"studies\": {\"1.2.3\": {\"series\": {\"1.2.4\": {\"modality\": 1}}}}}"}) {
        fs::remove_all(root);
        fs::create_directories(root);
        std::ofstream(root / "index.json") << text;
        LocalStore store(root);
        const std::string msg = errorOf([&] { store.studies(); });
        EXPECT_NE(msg.find((root / "index.json").string() + " cannot be read"), std::string::npos)
            << text << " -> " << msg;
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

// ---- The store against its peers: strict UIDs, no silent overwrite, Incoming, many writers ----

namespace {

std::string readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/** A small CT instance (4 x 4 pixels of `fill`) with the given UIDs. */
std::unique_ptr<DcmDataset> makeDataset(const std::string& studyUid, const std::string& seriesUid,
                                        const std::string& sopUid, Uint16 fill = 100) {
    auto ds = std::make_unique<DcmDataset>();
    ds->putAndInsertString(DCM_SOPClassUID, UID_CTImageStorage);
    ds->putAndInsertString(DCM_SOPInstanceUID, sopUid.c_str());
    ds->putAndInsertString(DCM_StudyInstanceUID, studyUid.c_str());
    ds->putAndInsertString(DCM_SeriesInstanceUID, seriesUid.c_str());
    ds->putAndInsertString(DCM_PatientName, "DOE^JANE");
    ds->putAndInsertString(DCM_Modality, "CT");
    ds->putAndInsertUint16(DCM_Rows, 4);
    ds->putAndInsertUint16(DCM_Columns, 4);
    ds->putAndInsertUint16(DCM_BitsAllocated, 16);
    ds->putAndInsertUint16(DCM_BitsStored, 16);
    ds->putAndInsertUint16(DCM_HighBit, 15);
    ds->putAndInsertUint16(DCM_PixelRepresentation, 0);
    ds->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
    const std::vector<Uint16> pixels(16, fill);
    ds->putAndInsertUint16Array(DCM_PixelData, pixels.data(), pixels.size());
    return ds;
}

/** Every regular file under `root` (recursively), as paths relative to it. */
std::vector<std::string> filesUnder(const fs::path& root) {
    std::vector<std::string> files;
    for (const auto& f : fs::recursive_directory_iterator(root))
        if (f.is_regular_file()) files.push_back(fs::relative(f.path(), root).string());
    std::sort(files.begin(), files.end());
    return files;
}

/** An instance to store: its records and its bytes (a DICOM file). */
struct Source {
    StudyRecord study;
    SeriesRecord series;
    std::string sop, bytes;
};

/** `n` synthetic instances of one study in two series. */
std::vector<Source> syntheticStudy(const std::string& studyUid, int n) {
    std::vector<Source> out;
    const fs::path tmp = fvr::test::tmpDir() / ("synthetic-" + studyUid + ".dcm");
    for (int i = 0; i < n; ++i) {
        const std::string series = studyUid + "." + std::to_string(1 + i % 2);
        const std::string sop = series + "." + std::to_string(i + 1);
        const auto ds = makeDataset(studyUid, series, sop, Uint16(i));
        DcmFileFormat file(ds.get());
        EXPECT_TRUE(file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit).good());
        out.push_back({study(studyUid), SeriesRecord{series, "CT", "", 0, 0}, sop, readBytes(tmp)});
    }
    fs::remove(tmp);
    return out;
}

/** The 93 slices of the shared head CT as they are on disk, or none without the shared data. */
std::vector<Source> headCt() {
    std::vector<Source> out;
    const fs::path dir = fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93";
    if (!fs::is_directory(dir)) return out;
    for (const auto& f : fs::directory_iterator(dir)) {
        DcmFileFormat file;
        if (file.loadFile(f.path().c_str()).bad()) continue;
        DcmDataset& ds = *file.getDataset();
        OFString sop;
        ds.findAndGetOFString(DCM_SOPInstanceUID, sop);
        out.push_back({detail::studyRecordFrom(ds), detail::seriesRecordFrom(ds), sop.c_str(),
                       readBytes(f.path())});
    }
    return out;
}

} // namespace

// The UID rule of PS3.5 9.1, nothing looser: the old rule took letters, '-' and '_', so a peer
// could name a study "index.json.part" (the store's temporary index) and break the store.
TEST(PacsLocalStore, UidsAreDicomUidsOnly) {
    for (const char* good : {"1", "1.2.3", "1.2.840.10008.5.1.4.1.1.2", "0.0", "1.02.003",
                             "1.2.826.0.1.3680043.2.1125.1.21134519937893837128465612345678901"})
        EXPECT_TRUE(isValidUid(good)) << good << ": " << uidProblem(good);
    const std::string long65 = "1." + std::string(63, '2');
    ASSERT_EQ(long65.size(), 65u);
    const std::pair<std::string, std::string> bad[] = {
        {"", "it is empty"},
        {long65, "it has 65 characters, at most 64"},
        {"index.json.part", "it contains \"i\", not a digit or a dot"},
        {"1.2.3a", "it contains \"a\""},
        {"1.2-3", "it contains \"-\""},
        {"1.2/3", "it contains \"/\""},
        {std::string("1.2\0.3", 6), "it contains \"\\x00\""},
        {"1.2\n", "it contains \"\\x0a\""},
        {".1.2", "it begins with a dot"},
        {"1.2.", "it ends with a dot"},
        {"1..2", "it has an empty component"},
        {".", "it begins with a dot"},
        {"..", "it begins with a dot"}};
    for (const auto& [uid, why] : bad) {
        EXPECT_FALSE(isValidUid(uid)) << uid;
        EXPECT_NE(uidProblem(uid).find(why), std::string::npos) << uid << " -> " << uidProblem(uid);
    }
    // The store's own names lie where no UID can reach.
    const fs::path root = "/store";
    for (const fs::path& own :
         {fs::path("index.json"), fs::path(".index.lock"), fs::path("incoming"),
          fs::path("quarantine"), temporaryPathFor(root / "index.json").filename(),
          temporaryPathFor(root / "1.2.3.dcm").filename(), temporaryPathFor(root / "1").filename(),
          fs::path("20260101T000000-1.2.3-1.dcm"), fs::path("1.2.3.dcm")})
        EXPECT_FALSE(isValidUid(own.string())) << own;
}

// Issue item 1: one C-STORE whose study UID was "index.json.part" made a folder of that name,
// and every later index write failed ("Is a directory"). Now each name of the store's own, and
// every other UID that is not one, is refused naming it, and the store goes on working.
TEST(PacsLocalStore, AnInstanceNamedLikeTheStoresOwnFilesIsRefusedAndTheStoreGoesOn) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-own-names";
    fs::remove_all(root);
    LocalStore store(root);
    ASSERT_EQ(
        detail::storeDataset(store, *makeDataset("1.2.3", "1.2.3.1", "1.2.3.1.1")).outcome.result,
        StoreResult::Stored);
    const std::string long65 = "1." + std::string(63, '2');
    int n = 0;
    for (const std::string bad : {"index.json.part", "index.json", ".index.lock", "incoming",
                                  "quarantine", "1.2.3a", long65.c_str(), "1..2", "..", "."}) {
        for (int position = 0; position < 3; ++position, ++n) {
            const auto ds =
                makeDataset(position == 0 ? bad : "1.2.3", position == 1 ? bad : "1.2.3.1",
                            position == 2 ? bad : "1.2.3.1.9");
            const Area area = n % 2 ? Area::Incoming : Area::Studies;
            const std::string msg = errorOf([&] { detail::storeDataset(store, *ds, area); });
            const char* what[] = {"study", "series", "SOP instance"};
            EXPECT_NE(msg.find(std::string("the ") + what[position] + " UID \"" + bad +
                               "\" cannot name a file in the local store: "),
                      std::string::npos)
                << bad << " -> " << msg;
        }
        EXPECT_NE(errorOf([&] { store.studyFolder(bad); }).find("\"" + bad + "\""),
                  std::string::npos);
        EXPECT_NE(errorOf([&] { store.remove(bad); }).find("cannot name a file"),
                  std::string::npos);
        EXPECT_NE(errorOf([&] { store.beginRetrieve(study(bad), ""); }).find("cannot name a file"),
                  std::string::npos);
    }
    // Nothing of theirs was made; the index and later stores still work.
    EXPECT_EQ(filesUnder(root), (std::vector<std::string>{
                                    ".index.lock", "1.2.3/1.2.3.1/1.2.3.1.1.dcm", "index.json"}));
    EXPECT_TRUE(fs::is_regular_file(root / "index.json"));
    store.beginRetrieve(study("1.2.4"), "");
    EXPECT_EQ(
        store.storeInstance(study("1.2.4"), {"1.2.4.1", "CT", "", 1, 1}, "1.2.4.1.1", "x").result,
        StoreResult::Stored);
    store.finishRetrieve("1.2.4", "", true);
    const auto entries = LocalStore(root).studies();
    ASSERT_EQ(entries.size(), 2u);
    EXPECT_TRUE(LocalStore(root).find("1.2.4")->complete);
    EXPECT_EQ(LocalStore(root).find("1.2.3")->instances, 1);
}

// Issue item 2 (tamper): a peer re-sent a slice of a complete study with the same UIDs and a
// bright block; the stored file was silently overwritten. Now the stored bytes stay, the new
// ones go to quarantine with a message, and the same bytes again change nothing.
TEST(PacsLocalStore, DifferentBytesUnderAStoredUidGoToQuarantine) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-tamper";
    fs::remove_all(root);
    LocalStore store(root);
    const std::vector<Source> two = syntheticStudy("1.2.5", 1);
    const Source& a = two[0];
    // The last bytes of the file are pixels: another dataset under the same UIDs.
    const std::string head = a.bytes.substr(0, a.bytes.size() - 8);
    const std::string tampered = head + "tampered";
    ASSERT_NE(tampered, a.bytes);
    const StoreOutcome first = store.storeInstance(a.study, a.series, a.sop, a.bytes);
    EXPECT_EQ(first.result, StoreResult::Stored);
    EXPECT_EQ(first.path, root / "1.2.5" / a.series.seriesUid / (a.sop + ".dcm"));
    EXPECT_TRUE(first.message.empty());
    store.finishRetrieve("1.2.5", "", true); // the study is complete

    const StoreOutcome again = store.storeInstance(a.study, a.series, a.sop, tampered);
    EXPECT_EQ(again.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(first.path), a.bytes); // untouched: equal to the source
    EXPECT_EQ(again.path.parent_path(), store.quarantineFolder());
    EXPECT_TRUE(std::regex_match(again.path.filename().string(),
                                 std::regex("[0-9]{8}T[0-9]{6}-" + a.sop + "-1\\.dcm")))
        << again.path;
    EXPECT_EQ(readBytes(again.path), tampered);
    for (const std::string& part :
         {"SOP instance " + a.sop, std::string("study 1.2.5"), again.path.string(),
          first.path.string() + " is kept unchanged"})
        EXPECT_NE(again.message.find(part), std::string::npos) << again.message;
    EXPECT_EQ(store.quarantined(), std::vector<fs::path>{again.path});

    // The same bytes as stored: nothing written, nothing new.
    const auto before = filesUnder(root);
    const StoreOutcome same = store.storeInstance(a.study, a.series, a.sop, a.bytes);
    EXPECT_EQ(same.result, StoreResult::Identical);
    EXPECT_EQ(same.path, first.path);
    EXPECT_EQ(filesUnder(root), before);
    // The same tampered bytes again: quarantined, no second copy; other bytes: a second file.
    const StoreOutcome repeated = store.storeInstance(a.study, a.series, a.sop, tampered);
    EXPECT_EQ(repeated.result, StoreResult::Quarantined);
    EXPECT_EQ(repeated.path, again.path);
    EXPECT_NE(repeated.message.find("the same bytes were quarantined before"), std::string::npos)
        << repeated.message;
    EXPECT_EQ(filesUnder(root), before);
    const StoreOutcome third = store.storeInstance(a.study, a.series, a.sop, head + "tamperd2");
    EXPECT_EQ(third.result, StoreResult::Quarantined);
    EXPECT_NE(third.path, again.path);
    EXPECT_EQ(readBytes(third.path), head + "tamperd2");
    EXPECT_EQ(readBytes(again.path), tampered);
    EXPECT_EQ(store.quarantined().size(), 2u);
    // The study stays as it was: complete, one instance (quarantine files are not its own).
    EXPECT_TRUE(store.find("1.2.5")->complete);
    EXPECT_EQ(store.find("1.2.5")->instances, 1);
    EXPECT_EQ(readBytes(first.path), a.bytes);
}

// The tamper case through what the listener and C-GET call, on a real slice when the shared
// data is there: a bright block in I70's pixels is quarantined, the stored slice kept.
TEST(PacsLocalStore, AReceivedSliceWithABrightBlockIsQuarantined) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-tamper-dataset";
    fs::remove_all(root);
    LocalStore store(root);
    const fs::path slice = fvr::test::sharedData() / "dicom/ct_head_slicer_64x64x93/CTHead70.dcm";
    DcmFileFormat file;
    std::unique_ptr<DcmDataset> synthetic;
    DcmDataset* ds = nullptr;
    if (fs::exists(slice)) {
        ASSERT_TRUE(file.loadFile(slice.c_str()).good());
        ds = file.getDataset();
        ASSERT_TRUE(ds->loadAllDataIntoMemory().good());
    } else { // without the shared data: a synthetic one
        synthetic = makeDataset("1.2.6", "1.2.6.1", "1.2.6.1.70");
        ds = synthetic.get();
    }
    const auto stored = detail::storeDataset(store, *ds);
    ASSERT_EQ(stored.outcome.result, StoreResult::Stored);
    const std::string original = readBytes(stored.outcome.path);
    EXPECT_EQ(detail::storeDataset(store, *ds).outcome.result, StoreResult::Identical);

    const Uint16* pixels = nullptr;
    unsigned long count = 0;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, pixels, &count).good());
    std::vector<Uint16> bright(pixels, pixels + count);
    for (unsigned long i = 0; i < std::min<unsigned long>(count, 8); ++i) bright[i] = 4000;
    ds->putAndInsertUint16Array(DCM_PixelData, bright.data(), count);
    const auto tampered = detail::storeDataset(store, *ds);
    EXPECT_EQ(tampered.outcome.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(stored.outcome.path), original);
    EXPECT_NE(readBytes(tampered.outcome.path), original);
    EXPECT_NE(tampered.outcome.message.find(stored.sopInstanceUid), std::string::npos);
    EXPECT_NE(tampered.outcome.message.find(stored.studyUid), std::string::npos);
}

// Unsolicited stores go to an Incoming area that never mixes into a study of the Studies area,
// even under the same UIDs.
TEST(PacsLocalStore, IncomingInstancesStayApartFromStudies) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-incoming";
    fs::remove_all(root);
    LocalStore store(root);
    const SeriesRecord series{"1.2.3.1", "CT", "head", 1, 1};
    const auto asked = store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "asked");
    const auto unasked =
        store.storeInstance(study("1.2.3"), series, "1.2.3.1.1", "unasked", Area::Incoming);
    EXPECT_EQ(asked.result, StoreResult::Stored);
    EXPECT_EQ(unasked.result, StoreResult::Stored); // not a tamper: another area
    EXPECT_EQ(asked.path, root / "1.2.3/1.2.3.1/1.2.3.1.1.dcm");
    EXPECT_EQ(unasked.path, root / "incoming/1.2.3/1.2.3.1/1.2.3.1.1.dcm");
    EXPECT_EQ(readBytes(asked.path), "asked");
    EXPECT_EQ(readBytes(unasked.path), "unasked");
    EXPECT_EQ(store.seriesFolder("1.2.3", "1.2.3.1", Area::Incoming), unasked.path.parent_path());

    const auto entries = LocalStore(root).studies();
    ASSERT_EQ(entries.size(), 2u);
    std::map<Area, LocalStore::Entry> byArea;
    for (const auto& e : entries) byArea[e.area] = e;
    ASSERT_EQ(byArea.size(), 2u);
    EXPECT_EQ(byArea[Area::Studies].folder, root / "1.2.3");
    EXPECT_EQ(byArea[Area::Incoming].folder, root / "incoming/1.2.3");
    for (const auto& [area, e] : byArea) {
        EXPECT_EQ(e.study.studyUid, "1.2.3");
        EXPECT_EQ(e.instances, 1);
        ASSERT_EQ(e.series.size(), 1u);
        EXPECT_EQ(e.series[0].instances, 1);
    }
    ASSERT_TRUE(store.find("1.2.3", Area::Incoming));
    EXPECT_EQ(store.find("1.2.3", Area::Incoming)->area, Area::Incoming);
    EXPECT_EQ(store.find("1.2.3")->area, Area::Studies);

    // The listener's rule applies per area: the incoming series is complete, the other not.
    store.markReceived("1.2.3", {"1.2.3.1"}, Area::Incoming);
    EXPECT_TRUE(store.find("1.2.3", Area::Incoming)->series[0].complete);
    EXPECT_FALSE(store.find("1.2.3")->series[0].complete);
    store.remove("1.2.3", Area::Incoming);
    EXPECT_FALSE(store.find("1.2.3", Area::Incoming));
    EXPECT_FALSE(fs::exists(root / "incoming/1.2.3"));
    EXPECT_EQ(readBytes(asked.path), "asked");
    EXPECT_TRUE(store.find("1.2.3"));
}

// An index written before the Incoming area (version 1, no "incoming") is read as it is, and
// kept when the store next writes.
TEST(PacsLocalStore, AnIndexOfVersion1IsRead) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-v1";
    fs::remove_all(root);
    fs::create_directories(root / "1.2.3/1.2.3.1");
    std::ofstream(root / "1.2.3/1.2.3.1/1.2.3.1.1.dcm") << "x";
    std::ofstream(root / "index.json")
        << R"({"version": 1, "studies": {"1.2.3": {"patientName": "DOE^J", "complete": true,
             "updated": "2024-01-01T00:00:00Z", "series": {"1.2.3.1": {"modality": "CT",
             "description": "", "complete": true}}}}})";
    LocalStore store(root);
    auto entry = store.find("1.2.3");
    ASSERT_TRUE(entry);
    EXPECT_TRUE(entry->complete);
    EXPECT_EQ(entry->instances, 1);
    EXPECT_EQ(entry->area, Area::Studies);
    store.storeInstance(study("1.2.4"), {"1.2.4.1", "MR", "", 1, 1}, "1.2.4.1.1", "y",
                        Area::Incoming);
    const nlohmann::json index = nlohmann::json::parse(readBytes(root / "index.json"));
    EXPECT_EQ(index.at("version"), 2);
    EXPECT_TRUE(index.at("studies").at("1.2.3").at("complete").get<bool>());
    EXPECT_TRUE(index.at("incoming").contains("1.2.4"));
    EXPECT_EQ(store.studies().size(), 2u);
}

namespace {

/** What one writer did: its outcomes by SOP instance, or the first error. */
struct WriterReport {
    std::map<std::string, StoreResult> outcomes;
    std::string error;
};

/** Stores `shared` (from `offset` on, wrapping) interleaved with `own`, through its own
 *  LocalStore object on `root`, as a separate process would. */
WriterReport runWriter(const fs::path& root, const std::vector<Source>& shared,
                       const std::vector<Source>& own, std::size_t offset) {
    WriterReport report;
    try {
        LocalStore store(root);
        const std::size_t n = std::max(shared.size(), own.size());
        for (std::size_t i = 0; i < n; ++i) {
            if (i < shared.size()) {
                const Source& s = shared[(i + offset) % shared.size()];
                report.outcomes[s.sop] =
                    store.storeInstance(s.study, s.series, s.sop, s.bytes).result;
            }
            if (i < own.size()) {
                const Source& s = own[i];
                report.outcomes[s.sop] =
                    store.storeInstance(s.study, s.series, s.sop, s.bytes).result;
            }
        }
    } catch (const std::exception& e) {
        report.error = e.what();
    }
    return report;
}

/** A child process's report through a pipe: "<result digit> <sop>" lines, or "E <message>". */
std::string encode(const WriterReport& r) {
    if (!r.error.empty()) return "E " + r.error + "\n";
    std::string out;
    for (const auto& [sop, result] : r.outcomes)
        out += std::to_string(static_cast<int>(result)) + " " + sop + "\n";
    return out;
}

WriterReport decode(const std::string& text) {
    WriterReport r;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("E ", 0) == 0)
            r.error = line.substr(2);
        else if (line.size() > 2)
            r.outcomes[line.substr(2)] = StoreResult(line[0] - '0');
    }
    return r;
}

} // namespace

// Issue item 4: concurrent retrieves into one store failed (2 of 9), every writer using the same
// temporary <SOP>.dcm.part ("cannot move the written file into place"). 8 threads, each with
// its own LocalStore object, and 3 child processes store the same study at once (in different
// orders) and a study of their own each.
TEST(PacsLocalStore, EightWritersAndThreeProcessesShareOneStore) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-concurrent";
    fs::remove_all(root);
    std::vector<Source> shared = headCt();
    if (shared.empty()) {
        std::cout << "[ note ] shared data not found: the common study is 93 synthetic instances\n";
        shared = syntheticStudy("1.2.826.0.1.3680043.2.1125.1", 93);
    }
    constexpr int kThreads = 8, kProcesses = 3;
    std::vector<std::vector<Source>> own;
    for (int w = 0; w < kThreads + kProcesses; ++w)
        own.push_back(syntheticStudy("1.2.826.0.1.3680043.2.1125.9." + std::to_string(w + 1), 24));

    const auto start = std::chrono::steady_clock::now();
    std::vector<std::pair<pid_t, int>> children; // pid, read end of its pipe
    for (int p = 0; p < kProcesses; ++p) {
        int fds[2];
        ASSERT_EQ(::pipe(fds), 0);
        const pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) { // the child: store, report, leave without the parent's atexit work
            ::close(fds[0]);
            const std::string text =
                encode(runWriter(root, shared, own[kThreads + p], 31 * (kThreads + p)));
            std::size_t done = 0;
            while (done < text.size()) {
                const ssize_t n = ::write(fds[1], text.data() + done, text.size() - done);
                if (n <= 0) ::_exit(2);
                done += std::size_t(n);
            }
            ::_exit(0);
        }
        ::close(fds[1]);
        children.emplace_back(pid, fds[0]);
    }
    std::vector<WriterReport> reports(kThreads);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] { reports[t] = runWriter(root, shared, own[t], 11 * t); });
    for (auto& t : threads) t.join();
    for (const auto& [pid, fd] : children) {
        std::string text;
        char buf[4096];
        for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) text.append(buf, std::size_t(n));
        ::close(fd);
        int status = 0;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
        reports.push_back(decode(text));
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "[ time ] " << kThreads + kProcesses << " writers, "
              << (kThreads + kProcesses) * (shared.size() + own[0].size()) << " stores: " << seconds
              << " s\n";

    // No error; each shared instance placed once and found identical by every other writer;
    // each writer's own instances placed by it; nothing quarantined.
    std::map<std::string, int> placed;
    for (std::size_t w = 0; w < reports.size(); ++w) {
        EXPECT_EQ(reports[w].error, "") << "writer " << w;
        EXPECT_EQ(reports[w].outcomes.size(), shared.size() + own[w].size()) << "writer " << w;
        for (const auto& [sop, result] : reports[w].outcomes) {
            EXPECT_NE(result, StoreResult::Quarantined) << sop;
            if (result == StoreResult::Stored) ++placed[sop];
        }
        for (const Source& s : own[w]) EXPECT_EQ(reports[w].outcomes[s.sop], StoreResult::Stored);
    }
    for (const Source& s : shared) EXPECT_EQ(placed[s.sop], 1) << s.sop;

    // Every file bit-equal to its source; no temporary left; the index valid and complete.
    LocalStore store(root);
    std::set<std::string> expectedFiles{".index.lock", "index.json"};
    std::vector<const std::vector<Source>*> all{&shared};
    for (const auto& o : own) all.push_back(&o);
    for (const auto* set : all)
        for (const Source& s : *set) {
            const fs::path file =
                store.seriesFolder(s.study.studyUid, s.series.seriesUid) / (s.sop + ".dcm");
            EXPECT_EQ(readBytes(file), s.bytes) << file;
            expectedFiles.insert(fs::relative(file, root).string());
        }
    const auto files = filesUnder(root);
    EXPECT_EQ(std::set<std::string>(files.begin(), files.end()), expectedFiles);
    const nlohmann::json index = nlohmann::json::parse(readBytes(root / "index.json"));
    for (const auto* set : all)
        for (const Source& s : *set)
            EXPECT_TRUE(
                index.at("studies").at(s.study.studyUid).at("series").contains(s.series.seriesUid))
                << s.study.studyUid << " / " << s.series.seriesUid;
    const auto entries = store.studies();
    EXPECT_EQ(entries.size(), all.size());
    for (const auto& e : entries)
        EXPECT_EQ(e.instances,
                  e.study.studyUid == shared[0].study.studyUid ? int(shared.size()) : 24)
            << e.study.studyUid;
}

// A process killed mid-write (kill -9) leaves its temporary file; the next retrieve into the
// study removes it, and keeps one whose writer still runs.
TEST(PacsLocalStore, ARetrieveRemovesTheTemporariesOfADeadWriter) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-stale";
    fs::remove_all(root);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) ::_exit(0);
    ASSERT_EQ(::waitpid(child, nullptr, 0), child); // its pid now names no process
    const std::string dead = std::to_string(child), alive = std::to_string(::getpid());
    const fs::path series = root / "1.2.3/1.2.3.1";
    fs::create_directories(series);
    const fs::path staleFile = series / (".1.2.3.1.1.dcm." + dead + ".0.part");
    const fs::path staleIndex = root / (".index.json." + dead + ".4.part");
    const fs::path live = series / (".1.2.3.1.2.dcm." + alive + ".0.part");
    const fs::path notOurs = series / "notes.part";
    // The form with the writer's pid space: ours with a dead pid goes; another host's or
    // container's (a store on NFS, shared with a container) stays, its pid means nothing here.
    const std::string ours = fvr::core::writerIdentity();
    const std::string other = ours == "00000000" ? "00000001" : "00000000";
    const fs::path staleOurs = series / (".1.2.3.1.3.dcm." + dead + "-" + ours + ".0.part");
    const fs::path indexOurs = root / (".index.json." + dead + "-" + ours + ".5.part");
    const fs::path foreign = series / (".1.2.3.1.4.dcm." + dead + "-" + other + ".0.part");
    const fs::path foreignIndex = root / (".index.json." + dead + "-" + other + ".5.part");
    for (const fs::path& p :
         {staleFile, staleIndex, live, notOurs, staleOurs, indexOurs, foreign, foreignIndex})
        std::ofstream(p) << "x";
    LocalStore store(root);
    store.beginRetrieve(study("1.2.3"), "");
    EXPECT_FALSE(fs::exists(staleFile));
    EXPECT_FALSE(fs::exists(staleIndex));
    EXPECT_FALSE(fs::exists(staleOurs));
    EXPECT_FALSE(fs::exists(indexOurs));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(notOurs));
    EXPECT_TRUE(fs::exists(foreign));
    EXPECT_TRUE(fs::exists(foreignIndex));
}

// The listener's Incoming area is never touched by a retrieve: a writer killed there left its
// temporary for good. The first store into a study folder removes the dead writers' ones (of
// this pid space), and keeps a live writer's and another host's.
TEST(PacsLocalStore, AStoreIntoIncomingRemovesTheTemporariesOfADeadWriter) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-stale-incoming";
    fs::remove_all(root);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) ::_exit(0);
    ASSERT_EQ(::waitpid(child, nullptr, 0), child);
    const std::string dead = std::to_string(child), alive = std::to_string(::getpid());
    const std::string ours = fvr::core::writerIdentity();
    const std::string other = ours == "00000000" ? "00000001" : "00000000";
    const fs::path series = root / "incoming/1.2.7/1.2.7.9";
    fs::create_directories(series);
    const fs::path stale = series / (".1.2.7.9.1.dcm." + dead + "-" + ours + ".0.part");
    const fs::path staleOld = series / (".1.2.7.9.2.dcm." + dead + ".0.part");
    const fs::path live = series / (".1.2.7.9.3.dcm." + alive + "-" + ours + ".0.part");
    const fs::path foreign = series / (".1.2.7.9.4.dcm." + dead + "-" + other + ".0.part");
    for (const fs::path& p : {stale, staleOld, live, foreign}) std::ofstream(p) << "x";
    LocalStore store(root);
    const auto ds = makeDataset("1.2.7", "1.2.7.1", "1.2.7.1.1");
    EXPECT_EQ(detail::storeDataset(store, *ds, Area::Incoming).outcome.result, StoreResult::Stored);
    EXPECT_FALSE(fs::exists(stale));
    EXPECT_FALSE(fs::exists(staleOld));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(foreign));
    EXPECT_EQ(store.find("1.2.7", Area::Incoming)->instances, 1);
}

// "The same instance" is the same dataset in the same transfer syntax, not the same file bytes:
// the meta header (group 0002) names the DCMTK that wrote the file, so after a DCMTK upgrade
// every resumed instance was quarantined and a study could never complete again.
TEST(PacsLocalStore, TheSameDatasetUnderAnotherMetaHeaderIsIdentical) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-meta";
    fs::remove_all(root);
    LocalStore store(root);
    const auto ds = makeDataset("1.2.8", "1.2.8.1", "1.2.8.1.1");
    const auto stored = detail::storeDataset(store, *ds);
    ASSERT_EQ(stored.outcome.result, StoreResult::Stored);
    // As an older DCMTK would have written it: another implementation class UID and version
    // name, of the same lengths (the meta header's group length stays right).
    std::string bytes = readBytes(stored.outcome.path);
    const auto replace = [&](const std::string& from, const std::string& to) {
        const std::size_t at = bytes.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        ASSERT_LT(at, 132u + 200u) << from; // in the meta header, not the dataset
        bytes.replace(at, from.size(), to);
    };
    replace(OFFIS_DTK_IMPLEMENTATION_VERSION_NAME,
            std::string(std::strlen(OFFIS_DTK_IMPLEMENTATION_VERSION_NAME), 'Z'));
    replace(OFFIS_IMPLEMENTATION_CLASS_UID,
            std::string(OFFIS_IMPLEMENTATION_CLASS_UID).substr(0, 18) +
                std::string(std::strlen(OFFIS_IMPLEMENTATION_CLASS_UID) - 18, '9'));
    { std::ofstream(stored.outcome.path, std::ios::binary) << bytes; }
    const auto again = detail::storeDataset(store, *ds);
    EXPECT_EQ(again.outcome.result, StoreResult::Identical) << again.outcome.message;
    EXPECT_EQ(readBytes(stored.outcome.path), bytes); // the stored file untouched
    EXPECT_TRUE(store.quarantined().empty());
    // One pixel changed: another dataset, quarantined as before.
    const std::vector<Uint16> pixels = [] {
        std::vector<Uint16> p(16, 100);
        p[5] = 101;
        return p;
    }();
    ds->putAndInsertUint16Array(DCM_PixelData, pixels.data(), pixels.size());
    const auto changed = detail::storeDataset(store, *ds);
    EXPECT_EQ(changed.outcome.result, StoreResult::Quarantined);
    EXPECT_EQ(readBytes(stored.outcome.path), bytes);
    EXPECT_EQ(store.quarantined().size(), 1u);
}

// A permitted sender could send endless variants of one SOP instance: the quarantine takes at
// most 3 files of one instance and a byte budget in all (1 GiB unless FVR_QUARANTINE_MAX_BYTES
// says otherwise); beyond, the instance is refused with WriteError (the listener answers
// 0xA700, Refused: Out of resources) naming the limit, and nothing is written.
TEST(PacsLocalStore, TheQuarantineIsCapped) {
    const fs::path root = fvr::test::tmpDir() / "pacs-store-quarantine-cap";
    fs::remove_all(root);
    ::unsetenv("FVR_QUARANTINE_MAX_BYTES");
    ::unsetenv("FVR_QUARANTINE_MAX_PER_INSTANCE");
    LocalStore store(root);
    const std::vector<Source> one = syntheticStudy("1.2.9", 2);
    for (const Source& s : one)
        ASSERT_EQ(store.storeInstance(s.study, s.series, s.sop, s.bytes).result,
                  StoreResult::Stored);
    const Source& a = one[0];
    const auto variant = [](const Source& s, int n) {
        return s.bytes.substr(0, s.bytes.size() - 8) + "variant" + std::to_string(n);
    };
    const auto refusal = [&](const Source& s, int n) {
        try {
            store.storeInstance(s.study, s.series, s.sop, variant(s, n));
        } catch (const fvr::core::WriteError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    for (int n = 1; n <= 3; ++n)
        EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, n)).result,
                  StoreResult::Quarantined);
    const auto before = filesUnder(root);
    std::string msg = refusal(a, 4);
    for (const std::string& part :
         {"SOP instance " + a.sop, store.quarantineFolder().string() + " is full",
          std::string("it holds 3 files of this instance, at most 3"),
          std::string("FVR_QUARANTINE_MAX_PER_INSTANCE"), std::string("refused")})
        EXPECT_NE(msg.find(part), std::string::npos) << msg;
    EXPECT_EQ(filesUnder(root), before); // nothing written, no temporary left
    // A quarantined variant sent again still answers as before (it takes no more room).
    EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, 2)).result,
              StoreResult::Quarantined);

    // The byte budget: room for one more file of the other instance, not two.
    const std::uintmax_t size = a.bytes.size();
    ::setenv("FVR_QUARANTINE_MAX_BYTES", std::to_string(4 * size + size / 2).c_str(), 1);
    const Source& b = one[1];
    EXPECT_EQ(store.storeInstance(b.study, b.series, b.sop, variant(b, 1)).result,
              StoreResult::Quarantined);
    msg = refusal(b, 2);
    for (const std::string& part : {"it holds " + std::to_string(4 * size) + " bytes",
                                    "budget of " + std::to_string(4 * size + size / 2) + " bytes",
                                    std::string("FVR_QUARANTINE_MAX_BYTES")})
        EXPECT_NE(msg.find(part), std::string::npos) << msg;
    ::setenv("FVR_QUARANTINE_MAX_BYTES", "lots", 1);
    msg = refusal(b, 3);
    EXPECT_NE(msg.find("FVR_QUARANTINE_MAX_BYTES=\"lots\" is not a count"), std::string::npos)
        << msg;
    ::unsetenv("FVR_QUARANTINE_MAX_BYTES");
    ::setenv("FVR_QUARANTINE_MAX_PER_INSTANCE", "4", 1);
    EXPECT_EQ(store.storeInstance(a.study, a.series, a.sop, variant(a, 4)).result,
              StoreResult::Quarantined);
    ::unsetenv("FVR_QUARANTINE_MAX_PER_INSTANCE");
    EXPECT_EQ(store.quarantined().size(), 5u);
    for (const Source& s : one)
        EXPECT_EQ(readBytes(store.find("1.2.9")->folder / s.series.seriesUid / (s.sop + ".dcm")),
                  s.bytes);
}
