// Which series of a scan opens: the default series (loadable, then most slices), a series named
// by key or UID, and loading it with the note that says which and why. openStudy (io/) and
// loadDicomFolder both follow these.
#include <algorithm>

#include "dicom_internal.h"

namespace fvr::core {
namespace fs = std::filesystem;

namespace {

void addOnce(std::vector<std::string>& list, const std::string& w) {
    if (std::find(list.begin(), list.end(), w) == list.end()) list.push_back(w);
}

/** The series `key` names (empty: the default one), with the note saying which and why. */
const DicomSeriesInfo& chooseSeries(const DicomScanResult& scan, const std::string& key,
                                    const fs::path& folder, std::vector<std::string>& notes) {
    if (!key.empty()) {
        std::string note;
        const DicomSeriesInfo& s = findSeries(scan, key, folder, &note);
        if (!note.empty()) notes.push_back(note);
        return s;
    }
    const DicomSeriesInfo& s = scan.series[defaultSeriesIndex(scan)];
    if (scan.series.size() > 1)
        notes.push_back(folder.string() + " holds " + std::to_string(scan.series.size()) +
                        " series; loaded " + s.key + " (the loadable one with most slices, " +
                        std::to_string(s.frameCount) + ")");
    return s;
}

} // namespace

std::size_t defaultSeriesIndex(const DicomScanResult& scan) {
    if (scan.series.empty()) throw DicomError("no image series in the scan");
    std::size_t best = 0;
    for (std::size_t i = 1; i < scan.series.size(); ++i) {
        const auto& s = scan.series[i];
        const auto& b = scan.series[best];
        if ((s.loadable() && !b.loadable()) ||
            (s.loadable() == b.loadable() && s.frameCount > b.frameCount))
            best = i;
    }
    return best;
}

const DicomSeriesInfo& findSeries(const DicomScanResult& scan, const std::string& key,
                                  const fs::path& folder, std::string* note) {
    for (const auto& s : scan.series)
        if (s.key == key) return s;
    const DicomSeriesInfo* first = nullptr;
    int parts = 0;
    for (const auto& s : scan.series)
        if (s.seriesUid == key) {
            if (!first) first = &s;
            ++parts;
        }
    if (!first) {
        std::string keys;
        for (const auto& s : scan.series) keys += (keys.empty() ? "" : ", ") + s.key;
        throw DicomError(folder.string() + ": no series '" + key + "' (found: " + keys + ")");
    }
    if (parts > 1 && note)
        *note = "series " + key + " was split; loaded its first part " + first->key;
    return *first;
}

DicomVolume loadChosenSeries(const DicomScanResult& scan, const std::string& key,
                             const fs::path& folder, const ProgressFn& progress,
                             const CancelToken* cancel, const DicomSeriesInfo** chosen) {
    std::vector<std::string> notes;
    const DicomSeriesInfo& s = chooseSeries(scan, key, folder, notes);
    DicomVolume loaded = loadDicomSeries(s, progress, cancel);
    for (const auto& w : loaded.warnings) addOnce(notes, w);
    for (const auto& w : s.warnings) addOnce(notes, w);
    for (const auto& w : scan.warnings) addOnce(notes, w);
    loaded.warnings = std::move(notes);
    if (chosen) *chosen = &s;
    return loaded;
}

DicomVolume loadDicomFolder(const fs::path& folder, const std::string& key) {
    return loadChosenSeries(scanDicomFolder(folder), key, folder);
}

} // namespace fvr::core
