// The workstation's PACS side without a network: nodes kept in the settings and checked with
// core's rules, the query the form describes, and the projection as DICOM Secondary Capture
// (what Send to PACS sends). The retrieve and send against a real Orthanc are in
// test_pacs_orthanc.cpp.
#include <QComboBox>
#include <QDateEdit>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QTableWidget>

#include <dcmtk/dcmdata/dctk.h>

#include <cmath>
#include <filesystem>
#include <vector>

#include <fvr/ui/pacs_dialog.h>
#include <fvr/ui/pacs_service.h>
#include <fvr/ui/pacs_settings.h>

#include "pacs/orthanc_server.h"
#include "ui/ui_support.h"

using namespace fvr;
using fvr::test::openAndWait;
using fvr::test::Workstation;
using fvr::ui::StudySource;
namespace pacs = fvr::core::pacs;

namespace {

pacs::Node node(const std::string& name, const std::string& ae, int port, pacs::RetrieveMethod m) {
    pacs::Node n;
    n.name = name;
    n.calledAe = ae;
    n.host = "127.0.0.1";
    n.port = port;
    n.retrieve = m;
    return n;
}

std::string date(const QDate& d) { return d.toString("yyyyMMdd").toStdString(); }

} // namespace

TEST_F(Workstation, PacsNodesPersistAndInvalidOnesAreRefusedWithTheReason) {
    ui::PacsSettings s;
    s.nodes = {node("Hospital", "ORTHANC", 4242, pacs::RetrieveMethod::Move),
               node("Lab", "LABPACS", 11113, pacs::RetrieveMethod::Get)};
    s.local.aeTitle = "FVRTEST";
    s.local.listenPort = 11500;
    s.listen = false;
    s.save();
    const ui::PacsSettings back = ui::PacsSettings::load();
    ASSERT_EQ(back.nodes.size(), 2u);
    EXPECT_EQ(back.nodes[0].calledAe, "ORTHANC");
    EXPECT_EQ(back.nodes[0].port, 4242);
    EXPECT_EQ(back.nodes[0].retrieve, pacs::RetrieveMethod::Move);
    EXPECT_EQ(back.nodes[1].name, "Lab");
    EXPECT_EQ(back.nodes[1].retrieve, pacs::RetrieveMethod::Get);
    EXPECT_EQ(back.local.aeTitle, "FVRTEST");
    EXPECT_EQ(back.local.listenPort, 11500);
    EXPECT_FALSE(back.listen); // off unless the user turns it on

    ui::PacsNodesDialog d(back);
    EXPECT_EQ(d.table()->rowCount(), 2);
    d.aeTitleEdit()->setText("   "); // all spaces (the field takes at most 16 characters)
    d.table()->item(1, 1)->setText("BAD\\AE");
    d.accept();
    EXPECT_NE(d.result(), QDialog::Accepted); // stays open and says why
    const QString why = d.errorLabel()->text();
    EXPECT_TRUE(d.errorLabel()->isVisibleTo(&d));
    EXPECT_TRUE(why.contains("our AE title")) << why.toStdString();
    EXPECT_TRUE(why.contains("BAD\\AE")) << why.toStdString();
    d.aeTitleEdit()->setText("FVR");
    d.table()->item(1, 1)->setText("LABPACS");
    d.accept();
    EXPECT_EQ(d.result(), QDialog::Accepted);
    EXPECT_EQ(d.settings().local.aeTitle, "FVR");
}

TEST_F(Workstation, PacsListenerTrustPersistsAndBadPeersAreRefused) {
    ui::PacsSettings s = ui::PacsSettings::load();
    EXPECT_EQ(s.local.listenAddress, "127.0.0.1"); // this machine only unless told otherwise
    EXPECT_TRUE(s.local.allowedPeers.empty()); // the nodes: for their C-MOVEs only
    s.local.listenAddress = "0.0.0.0";
    s.local.allowedPeers = {{"MODALITY", "10.0.0.7"}, {"ORTHANC", ""}};
    s.save();
    const ui::PacsSettings back = ui::PacsSettings::load();
    EXPECT_EQ(back.local.listenAddress, "0.0.0.0");
    EXPECT_EQ(back.local.allowedPeers, s.local.allowedPeers);

    ui::PacsNodesDialog d(back);
    EXPECT_EQ(d.allowedPeersEdit()->text(), "MODALITY@10.0.0.7, ORTHANC");
    d.allowedPeersEdit()->setText("GOOD, BAD\\AE@host, X@");
    d.listenAddressEdit()->setText("everywhere");
    d.accept();
    EXPECT_NE(d.result(), QDialog::Accepted);
    const QString why = d.errorLabel()->text();
    EXPECT_TRUE(why.contains("\"everywhere\" is not an IPv4 address")) << why.toStdString();
    EXPECT_TRUE(why.contains("BAD\\AE@host")) << why.toStdString();
    EXPECT_TRUE(why.contains("no host after '@'")) << why.toStdString();
    d.allowedPeersEdit()->setText("GOOD, LAB@10.0.0.8");
    d.listenAddressEdit()->setText("127.0.0.1");
    d.accept();
    EXPECT_EQ(d.result(), QDialog::Accepted);
    EXPECT_EQ(d.settings().local.allowedPeers,
              (std::vector<pacs::Peer>{{"GOOD", ""}, {"LAB", "10.0.0.8"}}));
}

// DICOM TLS: a node's TLS box and our certificate, key, CAs, peer check and listener mode are
// kept in the settings; OK with a TLS node names a certificate file that cannot be read.
TEST_F(Workstation, PacsTlsSettingsPersistAndAnUnreadableCertificateIsNamed) {
    ui::PacsSettings s;
    s.nodes = {node("Secure", "ORTHANC", 2762, pacs::RetrieveMethod::Get),
               node("Plain", "LABPACS", 4242, pacs::RetrieveMethod::Get)};
    s.nodes[0].tls = true;
    s.local.tls.certificateFile = "/certs/ours.pem";
    s.local.tls.privateKeyFile = "/certs/ours.key";
    s.local.tls.trustedCaFiles = {"/certs/ca1.pem", "/certs/ca2.pem"};
    s.local.tls.verifyPeer = false;
    s.local.listenTls = true;
    s.save();
    const ui::PacsSettings back = ui::PacsSettings::load();
    ASSERT_EQ(back.nodes.size(), 2u);
    EXPECT_TRUE(back.nodes[0].tls);
    EXPECT_FALSE(back.nodes[1].tls);
    EXPECT_EQ(back.local.tls.certificateFile, "/certs/ours.pem");
    EXPECT_EQ(back.local.tls.privateKeyFile, "/certs/ours.key");
    EXPECT_EQ(back.local.tls.trustedCaFiles,
              (std::vector<std::string>{"/certs/ca1.pem", "/certs/ca2.pem"}));
    EXPECT_FALSE(back.local.tls.verifyPeer);
    EXPECT_TRUE(back.local.listenTls);

    ui::PacsNodesDialog d(back);
    EXPECT_EQ(d.tlsTrustedCaEdit()->text(), "/certs/ca1.pem;/certs/ca2.pem");
    const ui::PacsSettings shown = d.settings(); // the dialog gives back what it was given
    EXPECT_TRUE(shown.nodes[0].tls);
    EXPECT_FALSE(shown.nodes[1].tls);
    EXPECT_EQ(shown.local.tls.trustedCaFiles, back.local.tls.trustedCaFiles);
    EXPECT_FALSE(shown.local.tls.verifyPeer);
    EXPECT_TRUE(shown.local.listenTls);
    d.accept(); // the files do not exist: OK names the first one read
    EXPECT_NE(d.result(), QDialog::Accepted);
    const QString why = d.errorLabel()->text();
    EXPECT_TRUE(why.contains("/certs/ours.pem cannot be read")) << why.toStdString();
}

// The running listener follows every setting it is made from: turned to TLS (or given other
// certificates, or another timeout) it is restarted with them, not left speaking plain DICOM.
TEST_F(Workstation, PacsListenerRestartsWhenItsTlsSettingsChange) {
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / "fvr-ui-listener-tls";
    std::filesystem::remove_all(dir);
    ui::PacsService service(dir / "store");
    ui::PacsSettings s;
    s.listen = true;
    s.local.listenPort = test::freeLoopbackPort();
    bool ok = false;
    const QString started = service.applyListener(s, &ok);
    ASSERT_TRUE(ok) << started.toStdString();
    EXPECT_TRUE(service.listening());
    EXPECT_TRUE(service.applyListener(s, &ok).isEmpty()); // nothing changed: left running
    s.local.listenTls = true;
    s.local.tls.certificateFile = (dir / "missing.pem").string();
    s.local.tls.privateKeyFile = (dir / "missing.key").string();
    const QString why = service.applyListener(s, &ok);
    EXPECT_FALSE(ok) << why.toStdString();
    EXPECT_FALSE(service.listening()); // not the plain listener of before
    EXPECT_TRUE(why.contains("not started: TLS")) << why.toStdString();
    std::filesystem::remove_all(dir);
}

TEST_F(Workstation, PacsQueryFormGivesTheDicomQuery) {
    ui::PacsSettings s;
    s.nodes = {node("Hospital", "ORTHANC", 4242, pacs::RetrieveMethod::Get)};
    s.save();
    ui::PacsDialog* d = window->pacsDialog();
    ASSERT_EQ(d->nodeCombo()->count(), 1);
    d->patientNameEdit()->setText("  DOE*  ");
    d->patientIdEdit()->setText("12345");
    pacs::StudyQuery q = d->query();
    EXPECT_EQ(q.patientName, "DOE*");
    EXPECT_EQ(q.patientId, "12345");
    EXPECT_TRUE(q.dateFrom.empty() && q.dateTo.empty()); // any date
    EXPECT_TRUE(q.modality.empty()); // any modality

    const QDate today = QDate::currentDate();
    d->datePresetCombo()->setCurrentIndex(3); // last 7 days: today and the 6 before
    q = d->query();
    EXPECT_EQ(q.dateFrom, date(today.addDays(-6)));
    EXPECT_EQ(q.dateTo, date(today));
    d->datePresetCombo()->setCurrentIndex(2); // yesterday
    q = d->query();
    EXPECT_EQ(q.dateFrom, date(today.addDays(-1)));
    EXPECT_EQ(q.dateTo, q.dateFrom);
    d->datePresetCombo()->setCurrentIndex(6); // a range the user picks
    EXPECT_TRUE(d->dateFromEdit()->isEnabled());
    d->dateFromEdit()->setDate(QDate(2015, 2, 1));
    d->dateToEdit()->setDate(QDate(2015, 2, 28));
    d->modalityCombo()->setCurrentText("ct");
    q = d->query();
    EXPECT_EQ(q.dateFrom, "20150201");
    EXPECT_EQ(q.dateTo, "20150228");
    EXPECT_EQ(q.modality, "CT");
}

TEST_F(Workstation, PacsGreyedDateFieldsShowWhatThePresetSearches) {
    ui::PacsSettings s;
    s.nodes = {node("Hospital", "ORTHANC", 4242, pacs::RetrieveMethod::Get)};
    s.save();
    ui::PacsDialog* d = window->pacsDialog();
    const QDate today = QDate::currentDate();
    d->datePresetCombo()->setCurrentIndex(1); // today
    EXPECT_FALSE(d->dateFromEdit()->isEnabled());
    EXPECT_EQ(d->dateFromEdit()->date(), today); // not a week back
    EXPECT_EQ(d->dateToEdit()->date(), today);
    d->datePresetCombo()->setCurrentIndex(4); // last 30 days
    EXPECT_EQ(d->dateFromEdit()->date(), today.addDays(-29));
    EXPECT_EQ(d->dateToEdit()->date(), today);
    EXPECT_EQ(d->query().dateFrom, date(today.addDays(-29)));
}

TEST_F(Workstation, ProjectionExportsAsDicomSecondaryCaptureWithItsValues) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    const auto p = window->views()[0]->projection();
    ASSERT_TRUE(p);
    const auto path = test::tmpDir() / "ui-projection.dcm";
    std::filesystem::remove(path);
    ASSERT_TRUE(window->exportProjection(QString::fromStdString(path.string())));
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(path.c_str()).good());
    DcmDataset* ds = file.getDataset();
    OFString sop;
    ds->findAndGetOFString(DCM_SOPClassUID, sop);
    EXPECT_EQ(sop, OFString(UID_SecondaryCaptureImageStorage));
    Uint16 rows = 0, cols = 0;
    ds->findAndGetUint16(DCM_Rows, rows);
    ds->findAndGetUint16(DCM_Columns, cols);
    ASSERT_EQ(int(rows), p->height);
    ASSERT_EQ(int(cols), p->width);
    Float64 slope = 0, intercept = 0;
    ds->findAndGetFloat64(DCM_RescaleSlope, slope);
    ds->findAndGetFloat64(DCM_RescaleIntercept, intercept);
    const Uint16* stored = nullptr;
    ASSERT_TRUE(ds->findAndGetUint16Array(DCM_PixelData, stored).good());
    double worst = 0;
    for (std::size_t i = 0; i < p->pixels.size(); ++i)
        worst = std::max(worst, std::abs(stored[i] * slope + intercept - p->pixels[i]));
    EXPECT_LE(worst, slope); // the float values back to within one stored step
    EXPECT_GT(slope, 0.0);
}

// One rule for showing a DICOM date (the Study panel and the PACS dialog had one each: the
// panel's turned "20231301" into "2023-13-01").
TEST(DicomDateShown, CalendarDaysAsIsoOthersAsTheyAre) {
    EXPECT_EQ(ui::dicomDate("20150206"), "2015-02-06");
    EXPECT_EQ(ui::dicomDate("20240229"), "2024-02-29");
    for (const char* other : {"", "2015", "20231301", "20230229", "2015-02-06", "1.2.3.4."})
        EXPECT_EQ(ui::dicomDate(other), QString::fromLatin1(other)) << other;
}
