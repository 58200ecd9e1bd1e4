// fvr-render and a PACS: dicom:// INPUT, --query, --send (core/pacs does the DIMSE work).
#include "pacs.h"

#include <chrono>
#include <cstdio>
#include <sstream>

#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/pacs/dicom_url.h>
#include <fvr/core/pacs/local_store.h>

#include "json_output.h"

namespace fvr::cli {
namespace {

using core::SettingsError;
namespace pacs = core::pacs;

void setDates(pacs::StudyQuery& q, const std::string& term, const std::string& value) {
    const auto dash = value.find('-');
    q.dateFrom = value.substr(0, dash);
    q.dateTo = dash == std::string::npos ? value : value.substr(dash + 1);
    try {
        pacs::studyDateMatch(q);
    } catch (const pacs::PacsError& e) {
        throw SettingsError("--query: '" + term +
                            "': expected StudyDate=YYYYMMDD or YYYYMMDD-YYYYMMDD (either end may "
                            "be left open): " +
                            e.what());
    }
}

void addTerm(pacs::StudyQuery& q, const std::string& term) {
    const auto eq = term.find('=');
    if (eq == std::string::npos) throw SettingsError("--query: '" + term + "': expected KEY=VALUE");
    const std::string key = term.substr(0, eq), value = term.substr(eq + 1);
    if (key == "PatientName")
        q.patientName = value;
    else if (key == "PatientID")
        q.patientId = value;
    else if (key == "AccessionNumber")
        q.accessionNumber = value;
    else if (key == "Modality")
        q.modality = value;
    else if (key == "StudyDate")
        setDates(q, term, value);
    else
        throw SettingsError("--query: unknown key '" + key +
                            "' (expected PatientName, PatientID, AccessionNumber, StudyDate or "
                            "Modality)");
}

pacs::DicomUrl parseUrl(const std::string& what, const std::string& text) {
    try {
        return pacs::parseDicomUrl(text);
    } catch (const pacs::PacsError& e) {
        throw SettingsError(what + ": " + e.what());
    }
}

Json nullable(int v) { return v < 0 ? Json(nullptr) : Json(v); }

Json studyJson(const pacs::StudyRecord& s, const pacs::DicomUrl& url) {
    pacs::DicomUrl at = url;
    at.studyUid = s.studyUid;
    at.seriesUid.clear();
    Json j{{"studyUid", s.studyUid}, {"url", pacs::toString(at)}};
    for (const pacs::StudyTextField& f : pacs::studyTextFields()) j[f.name] = s.*f.member;
    j["numberOfSeries"] = nullable(s.numberOfSeries);
    j["numberOfInstances"] = nullable(s.numberOfInstances);
    return j;
}

Json seriesJson(const pacs::SeriesRecord& s) {
    return Json{{"seriesUid", s.seriesUid},
                {"modality", s.modality},
                {"description", s.description},
                {"seriesNumber", nullable(s.seriesNumber)},
                {"numberOfInstances", nullable(s.numberOfInstances)}};
}

/** The retrieve's progress on stderr: a line that rewrites itself on a terminal, else a line
 *  every 10%. */
pacs::RetrieveProgressFn progressLine(const std::string& what) {
    const bool tty = isatty(2);
    return [what, tty, lastTenth = -1](const pacs::RetrieveProgress& p) mutable {
        char of[32] = "";
        if (p.expected > 0) std::snprintf(of, sizeof of, "/%d", p.expected);
        if (tty) {
            std::fprintf(stderr, "\rretrieving %s: %d%s images", what.c_str(), p.received, of);
            return;
        }
        const int tenth = p.expected > 0 ? 10 * p.received / p.expected : p.received / 100;
        if (tenth != lastTenth)
            std::fprintf(stderr, "retrieving %s: %d%s images\n", what.c_str(), p.received, of);
        lastTenth = tenth;
    };
}

} // namespace

pacs::LocalAe localAe(const Options& o) {
    pacs::LocalAe local;
    local.aeTitle = o.aeTitle;
    local.listenPort = o.listenPort;
    // The listener of --retrieve move: bound where asked, allowing no peer but the node it
    // retrieves from, for that move only (no allowedPeers: nothing else is received).
    local.listenAddress = o.listenAddress;
    local.timeoutSeconds = o.pacsTimeout;
    local.tls.certificateFile = o.tlsCert;
    local.tls.privateKeyFile = o.tlsKey;
    local.tls.trustedCaFiles = o.tlsCa;
    local.tls.verifyPeer = !o.tlsNoVerify;
    local.listenTls = o.tls;
    return local;
}

pacs::DicomUrl parseNode(const Options& o, const std::string& text) {
    pacs::DicomUrl url = pacs::parseDicomUrl(text);
    url.node.retrieve = o.retrieve;
    url.node.tls = o.tls;
    return url;
}

pacs::StudyQuery parseStudyQuery(const std::vector<std::string>& terms) {
    pacs::StudyQuery q;
    for (const auto& option : terms) {
        std::stringstream ss(option);
        for (std::string term; std::getline(ss, term, ',');)
            if (!term.empty()) addTerm(q, term);
    }
    return q;
}

void checkPacsOptions(const Options& o) {
    const bool url = pacs::isDicomUrl(o.input);
    try {
        pacs::validateListener(localAe(o));
    } catch (const pacs::PacsError& e) {
        throw SettingsError(
            std::string("--ae-title/--listen-port/--listen-address/--pacs-timeout: ") + e.what());
    }
    if (o.queryGiven) {
        if (!url) throw SettingsError("--query: INPUT must be a PACS, dicom://AE@host:port");
        parseStudyQuery(o.query);
    }
    if (o.refresh && (!url || o.queryGiven))
        throw SettingsError("--refresh: INPUT must be a study (or series) on a PACS, "
                            "dicom://AE@host:port/STUDY_UID[/SERIES_UID], without --query");
    if (url) {
        const pacs::DicomUrl u = parseUrl("INPUT", o.input);
        if (!o.queryGiven && u.studyUid.empty())
            throw SettingsError("INPUT " + o.input +
                                ": no study UID to retrieve (dicom://AE@host:port/STUDY_UID"
                                "[/SERIES_UID]; --query finds studies)");
        if (!o.raw && !o.series.empty() && !u.seriesUid.empty() && o.series != u.seriesUid)
            throw SettingsError("--series: INPUT names series " + u.seriesUid + " already");
    }
    if (!o.send.empty()) {
        const pacs::DicomUrl u = parseUrl("--send", o.send);
        if (!u.studyUid.empty())
            throw SettingsError("--send: " + o.send + ": a node, dicom://AE@host:port, no UIDs");
        if (o.out.empty()) throw SettingsError("--send: needs --out FILE (the views to send)");
    }
}

std::filesystem::path retrieveInput(const Options& o) {
    const pacs::DicomUrl url = parseNode(o, o.input);
    pacs::LocalStore store(o.store.empty() ? pacs::defaultLocalStoreRoot()
                                           : std::filesystem::path(o.store));
    const std::string what =
        url.seriesUid.empty() ? "study " + url.studyUid : "series " + url.seriesUid;
    // Only what the store lacks: nothing (and no network) for a complete study, the missing
    // instances of a partial one, everything again with --refresh.
    const auto t0 = std::chrono::steady_clock::now();
    const pacs::RetrieveSummary done =
        pacs::retrieveMissing(url.node, localAe(o), url.studyUid, url.seriesUid, store,
                              progressLine(what), nullptr, o.refresh);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (done.fromStore) {
        std::fprintf(stderr, "%s is complete in the local store (%s): nothing retrieved\n",
                     what.c_str(), done.folder.string().c_str());
        return done.folder;
    }
    if (isatty(2)) std::fprintf(stderr, "\n");
    const char* how = o.retrieve == pacs::RetrieveMethod::Move ? "C-MOVE" : "C-GET";
    char counts[96];
    if (done.present == 0)
        std::snprintf(counts, sizeof counts, "%d images", done.fetched);
    else
        std::snprintf(counts, sizeof counts, "%d of %d images fetched, %d already local,",
                      done.fetched, done.fetched + done.present, done.present);
    std::fprintf(stderr, "retrieved %s from %s (%s, %s in %.2f s) into %s\n", what.c_str(),
                 pacs::describe(url.node).c_str(), how, counts, s, done.folder.string().c_str());
    return done.folder;
}

int runQuery(const Options& o) {
    const pacs::DicomUrl url = parseNode(o, o.input);
    const auto studies = pacs::findStudies(url.node, localAe(o), parseStudyQuery(o.query));
    Json out = Json::array();
    for (const auto& s : studies) {
        Json j = studyJson(s, url);
        if (o.querySeries) {
            j["series"] = Json::array();
            for (const auto& series : pacs::findSeries(url.node, localAe(o), s.studyUid))
                j["series"].push_back(seriesJson(series));
        }
        out.push_back(std::move(j));
    }
    printJson(out);
    return 0;
}

void sendViews(const Options& o, const std::vector<std::filesystem::path>& files, const char* what,
               const char* noun) {
    const pacs::DicomUrl url = parseNode(o, o.send);
    pacs::sendFiles(url.node, localAe(o), files);
    std::fprintf(stderr, "sent %zu %s%s to %s (%s, C-STORE)\n", files.size(), noun,
                 files.size() == 1 ? "" : "s", pacs::describe(url.node).c_str(), what);
}

} // namespace fvr::cli
