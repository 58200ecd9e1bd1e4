// Scanning a folder for DICOM series: the file list (DICOMDIR or a recursive walk), headers read
// in parallel without pixel data, and the grouping of files (and frames) into series.
//
// Grouping: by SeriesInstanceUID (files without one: by folder, study and series number). Within
// a series, frames are split apart where they cannot form one volume: image size, pixel spacing,
// orientation (row/column cosines differing by more than 1e-3) and echo (EchoNumbers or the
// enhanced MR EffectiveEchoTime) always split. When a part still holds two images at the same
// position, the first of AcquisitionNumber, temporal position, StackID, ImageType/FrameType,
// trigger time, b-value, rescale, a DimensionIndexValues entry, or the file, that separates it
// into parts without duplicates (the fewest parts wins; parts average at least two slices) splits
// it. Otherwise it stays whole and its warnings say that loading refuses the duplicates.
#include "dicom_internal.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <unordered_map>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcsequen.h>

#include <fvr/core/text.h>
#include <fvr/core/thread_pool.h>

namespace fvr::core {

using namespace dicom_detail;

namespace dicom_detail {

namespace {

struct Unit {
    int h = 0; // header index
    int f = 0; // frame
};

/** `dir / name` matched case-insensitively (ISO 9660 names in a DICOMDIR are upper case, the
 *  files on disk may not be). */
std::optional<fs::path> findCaseInsensitive(const fs::path& dir, const std::string& name) {
    std::error_code ec;
    if (fs::exists(dir / name, ec)) return dir / name;
    for (fs::directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
         !ec && it != end; it.increment(ec)) {
        if (iequals(it->path().filename().string(), name)) return it->path();
    }
    return std::nullopt;
}

/** Files referenced by a DICOMDIR; nullopt when it cannot be read. */
std::optional<std::vector<fs::path>> filesFromDicomdir(const fs::path& dicomdir,
                                                       std::vector<std::string>& skipped,
                                                       std::string& why) {
    DcmFileFormat ff;
    const OFCondition c = ff.loadFile(OFFilename(dicomdir.c_str()));
    if (c.bad()) {
        why = c.text();
        return std::nullopt;
    }
    DcmSequenceOfItems* records = nullptr;
    if (ff.getDataset()->findAndGetSequence(DCM_DirectoryRecordSequence, records).bad() ||
        !records) {
        why = "no DirectoryRecordSequence (0004,1220)";
        return std::nullopt;
    }
    const fs::path root = dicomdir.parent_path();
    std::vector<fs::path> files;
    std::set<fs::path> seen;
    for (unsigned long i = 0; i < records->card(); ++i) {
        DcmItem* rec = records->getItem(i);
        OFString id;
        if (!rec || rec->findAndGetOFStringArray(DCM_ReferencedFileID, id).bad() || id.empty())
            continue;
        // Components are separated by backslashes; never leave the DICOMDIR's folder.
        std::vector<std::string> parts;
        std::string cur;
        for (char ch : std::string(id.c_str())) {
            if (ch == '\\') {
                parts.push_back(cur);
                cur.clear();
            } else if (ch != ' ') {
                cur += ch;
            }
        }
        parts.push_back(cur);
        bool bad = false;
        fs::path p = root;
        for (const std::string& part : parts) {
            if (part.empty() || part == "." || part == ".." ||
                part.find('/') != std::string::npos) {
                bad = true;
                break;
            }
            auto found = findCaseInsensitive(p, part);
            p = found ? *found : p / part;
        }
        if (bad) {
            skipped.push_back(dicomdir.string() + ": record " + std::to_string(i + 1) +
                              " has an invalid ReferencedFileID '" + std::string(id.c_str()) + "'");
            continue;
        }
        std::error_code ec;
        const fs::file_status st = fs::status(p, ec); // stat(2): never opens the file
        if (!fs::is_regular_file(st)) {
            skipped.push_back(p.string() + (fs::exists(st)
                                                ? ": listed in DICOMDIR but not a regular file"
                                                : ": listed in DICOMDIR but missing"));
            continue;
        }
        if (seen.insert(p).second) files.push_back(p);
    }
    return files;
}

const FrameInfo& info(const std::vector<DicomHeader>& hs, const Unit& u) {
    return hs[static_cast<std::size_t>(u.h)].frameInfo[static_cast<std::size_t>(u.f)];
}

bool realPosition(const FrameInfo& f) { return f.hasPosition && !f.fileLevelPosition; }

/** Two units of the group at the same place along the slice normal. */
bool hasDuplicates(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units) {
    if (units.size() < 2) return false;
    const FrameInfo& f0 = info(hs, units[0]);
    Vec3 n{0, 0, 1};
    if (f0.hasOrientation) {
        const auto& o = f0.orientation;
        n = {o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5], o[0] * o[4] - o[1] * o[3]};
    }
    std::vector<double> t;
    for (const Unit& u : units) {
        const FrameInfo& f = info(hs, u);
        if (realPosition(f))
            t.push_back(f.position[0] * n[0] + f.position[1] * n[1] + f.position[2] * n[2]);
    }
    std::sort(t.begin(), t.end());
    for (std::size_t k = 0; k + 1 < t.size(); ++k)
        if (t[k + 1] - t[k] < 0.01) return true;
    return false;
}

using KeyFn = std::function<std::string(const Unit&)>;

std::vector<std::vector<Unit>> partition(const std::vector<Unit>& units, const KeyFn& key) {
    std::vector<std::vector<Unit>> parts;
    std::unordered_map<std::string, std::size_t> index;
    for (const Unit& u : units) {
        const std::string k = key(u);
        auto [it, inserted] = index.try_emplace(k, parts.size());
        if (inserted) parts.emplace_back();
        parts[it->second].push_back(u);
    }
    return parts;
}

struct Split {
    std::vector<std::vector<Unit>> parts;
    std::string by; // what split it, empty if not split
    bool duplicates = false;
};

Split resolveDuplicates(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units) {
    Split result;
    if (!hasDuplicates(hs, units)) {
        result.parts = {units};
        return result;
    }
    std::size_t maxDims = 0;
    for (const Unit& u : units) maxDims = std::max(maxDims, info(hs, u).dimensionIndex.size());
    std::vector<std::pair<std::string, KeyFn>> candidates = {
        {"AcquisitionNumber (0020,0012)", [&](const Unit& u) { return info(hs, u).acquisition; }},
        {"temporal position", [&](const Unit& u) { return info(hs, u).temporal; }},
        {"StackID (0020,9056)", [&](const Unit& u) { return info(hs, u).stack; }},
        {"ImageType/FrameType", [&](const Unit& u) { return info(hs, u).imageType; }},
        {"trigger time", [&](const Unit& u) { return info(hs, u).triggerTime; }},
        {"DiffusionBValue", [&](const Unit& u) { return info(hs, u).diffusion; }},
        {"RescaleSlope/Intercept",
         [&](const Unit& u) {
             return fmt(info(hs, u).slope, 9) + "/" + fmt(info(hs, u).intercept, 9);
         }},
    };
    const std::size_t combinable = candidates.size();
    for (std::size_t j = 0; j < maxDims; ++j)
        candidates.emplace_back("DimensionIndexValues (0020,9157) entry " + std::to_string(j + 1),
                                [&, j](const Unit& u) {
                                    const auto& d = info(hs, u).dimensionIndex;
                                    return j < d.size() ? std::to_string(d[j]) : std::string("-");
                                });
    candidates.emplace_back("file", [](const Unit& u) { return std::to_string(u.h); });
    candidates.emplace_back("the combination of acquisition attributes", [&](const Unit& u) {
        std::string k;
        for (std::size_t c = 0; c < combinable; ++c) k += candidates[c].second(u) + "|";
        return k;
    });

    for (const auto& [name, key] : candidates) {
        auto parts = partition(units, key);
        if (parts.size() < 2 || parts.size() * 2 > units.size()) continue;
        bool clean = true;
        for (const auto& p : parts) clean = clean && !hasDuplicates(hs, p);
        if (clean && (result.parts.empty() || parts.size() < result.parts.size())) {
            result.parts = std::move(parts);
            result.by = name;
        }
    }
    if (result.parts.empty()) {
        result.parts = {units};
        result.duplicates = true;
    }
    return result;
}

/** Header indices in order, repeated SOP instances (the same image copied twice) counted once:
 *  the repeats go to `skipped`. */
std::vector<int> uniqueInstances(const std::vector<DicomHeader>& hs,
                                 std::vector<std::string>& skipped) {
    std::vector<int> usable;
    std::unordered_map<std::string, int> seen;
    for (int i = 0; i < int(hs.size()); ++i) {
        const auto& uid = hs[static_cast<std::size_t>(i)].sopInstanceUid;
        if (!uid.empty()) {
            auto [it, inserted] = seen.try_emplace(uid, i);
            if (!inserted) {
                skipped.push_back(hs[static_cast<std::size_t>(i)].path.string() +
                                  ": duplicate of " +
                                  hs[static_cast<std::size_t>(it->second)].path.string() +
                                  " (same SOPInstanceUID)");
                continue;
            }
        }
        usable.push_back(i);
    }
    return usable;
}

/** Files of one SeriesInstanceUID (or folder/study/series number when it is missing). */
struct PrimaryGroup {
    std::string key; ///< the UID, or "folder:<folder>[#number][@study]"
    std::vector<int> members; ///< header indices
};

/** The groups in order of their first file. */
std::vector<PrimaryGroup> groupBySeriesUid(const std::vector<DicomHeader>& hs,
                                           const std::vector<int>& usable) {
    std::vector<PrimaryGroup> groups;
    std::unordered_map<std::string, std::size_t> index;
    for (int i : usable) {
        const DicomHeader& h = hs[static_cast<std::size_t>(i)];
        std::string key = h.seriesUid;
        if (key.empty())
            key = "folder:" + h.path.parent_path().string() +
                  (h.seriesNumber.empty() ? "" : "#" + h.seriesNumber) +
                  (h.studyUid.empty() ? "" : "@" + h.studyUid);
        auto [it, inserted] = index.try_emplace(key, groups.size());
        if (inserted) groups.push_back({key, {}});
        groups[it->second].members.push_back(i);
    }
    return groups;
}

/** Every frame of the files. */
std::vector<Unit> unitsOf(const std::vector<DicomHeader>& hs, const std::vector<int>& members) {
    std::vector<Unit> units;
    for (int i : members)
        for (int f = 0; f < int(hs[static_cast<std::size_t>(i)].frames); ++f)
            units.push_back({i, f});
    return units;
}

/** The split that always applies: frames that differ in image size, pixel spacing, orientation or
 *  echo never form one volume. */
struct HardSplit {
    std::vector<std::vector<Unit>> parts;
    std::string reason; ///< what differs ("image size, orientation"...); empty when not split
};

/** What differs between the parts of a hard split, given the number of distinct orientations and
 *  pixel spacings found. */
std::string hardSplitReason(const std::vector<DicomHeader>& hs,
                            const std::vector<std::vector<Unit>>& parts, std::size_t orientations,
                            std::size_t spacings) {
    std::set<std::string> sizes, echoes;
    for (const auto& p : parts) {
        const DicomHeader& h = hs[static_cast<std::size_t>(p[0].h)];
        sizes.insert(std::to_string(h.cols) + "x" + std::to_string(h.rows));
        echoes.insert(info(hs, p[0]).echo);
    }
    std::string what;
    if (sizes.size() > 1) what += "image size";
    if (orientations > 1) what += std::string(what.empty() ? "" : ", ") + "orientation";
    if (spacings > 1) what += std::string(what.empty() ? "" : ", ") + "pixel spacing";
    if (echoes.size() > 1) what += std::string(what.empty() ? "" : ", ") + "echo";
    return what;
}

HardSplit splitByImageGeometry(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units) {
    // Orientations (cosines within 1e-3) and pixel spacings (within 1e-3 relative) that match
    // share an id; -1 when absent.
    std::vector<std::array<double, 6>> iops;
    std::vector<std::pair<double, double>> spacings;
    auto iopId = [&](const FrameInfo& f) -> int {
        if (!f.hasOrientation) return -1;
        for (std::size_t k = 0; k < iops.size(); ++k) {
            double d = 0;
            for (int j = 0; j < 6; ++j)
                d = std::max(d, std::abs(iops[k][static_cast<std::size_t>(j)] -
                                         f.orientation[static_cast<std::size_t>(j)]));
            if (d <= 1e-3) return int(k);
        }
        iops.push_back(f.orientation);
        return int(iops.size()) - 1;
    };
    auto spacingId = [&](const FrameInfo& f) -> int {
        if (!f.hasPixelSpacing) return -1;
        for (std::size_t k = 0; k < spacings.size(); ++k)
            if (std::abs(spacings[k].first - f.rowSpacing) <= 1e-3 * f.rowSpacing &&
                std::abs(spacings[k].second - f.colSpacing) <= 1e-3 * f.colSpacing)
                return int(k);
        spacings.emplace_back(f.rowSpacing, f.colSpacing);
        return int(spacings.size()) - 1;
    };
    HardSplit result;
    result.parts = partition(units, [&](const Unit& u) {
        const DicomHeader& h = hs[static_cast<std::size_t>(u.h)];
        const FrameInfo& f = info(hs, u);
        return std::to_string(h.cols) + "x" + std::to_string(h.rows) + "|" +
               std::to_string(spacingId(f)) + "|" + std::to_string(iopId(f)) + "|" + f.echo;
    });
    if (result.parts.size() > 1)
        result.reason = hardSplitReason(hs, result.parts, iops.size(), spacings.size());
    return result;
}

/** One series of the scan result: a part of a hard split, split further where that resolves
 *  duplicate positions. */
struct Part {
    std::vector<Unit> units;
    std::string note; ///< what split it apart from the hard split (empty: nothing)
    bool duplicates = false; ///< duplicate positions remain (loading refuses them)
};

std::vector<Part> splitDuplicates(const std::vector<DicomHeader>& hs,
                                  const std::vector<std::vector<Unit>>& hardParts) {
    std::vector<Part> parts;
    for (const auto& part : hardParts) {
        Split s = resolveDuplicates(hs, part);
        for (auto& p : s.parts) parts.push_back({std::move(p), s.by, s.duplicates});
    }
    return parts;
}

/** The series' identity from its first file, the missing-UID warning, and the split warning
 *  when the group (key `groupKey`) became `count` series, this being part `g` (0-based). */
DicomSeriesInfo seriesIdentity(const DicomHeader& h0, const std::string& groupKey, std::size_t g,
                               std::size_t count, const std::string& splitWhy) {
    const bool split = count > 1;
    DicomSeriesInfo si;
    si.seriesUid = h0.seriesUid;
    si.key = (h0.seriesUid.empty() ? groupKey : h0.seriesUid) +
             (split ? "#" + std::to_string(g + 1) : std::string());
    si.studyUid = h0.studyUid;
    si.patientName = h0.patientName;
    si.patientId = h0.patientId;
    si.studyDate = h0.studyDate;
    si.seriesNumber = h0.seriesNumber;
    si.study = h0.study;
    si.modality = h0.modality;
    si.description = h0.description;
    si.transferSyntax = h0.xferName;
    if (h0.seriesUid.empty())
        si.warnings.push_back("SeriesInstanceUID (0020,000E) missing: files grouped by folder" +
                              std::string(h0.seriesNumber.empty() ? "" : ", series number") +
                              (h0.studyUid.empty() ? "" : " and study"));
    if (split)
        si.warnings.push_back("series " + (h0.seriesUid.empty() ? groupKey : h0.seriesUid) +
                              " split by " + splitWhy + " into " + std::to_string(count) +
                              " series; this is part " + std::to_string(g + 1));
    return si;
}

/** "<file>: <reason>" for the first unit whose pixel format cannot be loaded; empty if none. */
std::string firstUnsupported(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units) {
    for (const Unit& u : units) {
        const std::string why = unsupportedReason(hs[static_cast<std::size_t>(u.h)]);
        if (!why.empty()) return hs[static_cast<std::size_t>(u.h)].path.string() + ": " + why;
    }
    return {};
}

/** The files' malformed attributes as warnings, each problem once. */
void addHeaderProblems(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units,
                       std::vector<std::string>& warnings) {
    std::set<std::string> problems;
    for (const Unit& u : units)
        for (const auto& p : hs[static_cast<std::size_t>(u.h)].problems)
            if (problems.insert(p).second)
                warnings.push_back(hs[static_cast<std::size_t>(u.h)].path.filename().string() +
                                   ": " + p);
}

/** Plans the series as the loader will, to report dims, spacing and geometry problems now (and
 *  why it cannot be loaded). Returns its units in slice order (as given when planning failed). */
std::vector<Unit> planSeries(const std::vector<DicomHeader>& hs, const std::vector<Unit>& units,
                             DicomSeriesInfo& si) {
    const DicomHeader& h0 = hs[static_cast<std::size_t>(units[0].h)];
    std::vector<PlanSlice> slices;
    for (const Unit& u : units) {
        const DicomHeader& h = hs[static_cast<std::size_t>(u.h)];
        slices.push_back({&info(hs, u), sliceLabel(h, u.f), h.frames > 1, h.gantryTilt, u.h});
    }
    std::vector<Unit> ordered = units;
    std::string cannot = firstUnsupported(hs, units);
    addHeaderProblems(hs, units, si.warnings);
    const FrameInfo& fi0 = info(hs, units[0]);
    si.dims = {h0.cols, h0.rows, std::int64_t(units.size())};
    si.spacing = {fi0.hasPixelSpacing ? fi0.colSpacing : 1.0,
                  fi0.hasPixelSpacing ? fi0.rowSpacing : 1.0, 0.0};
    try {
        for (const Unit& u : units)
            if (hs[static_cast<std::size_t>(u.h)].rows != h0.rows ||
                hs[static_cast<std::size_t>(u.h)].cols != h0.cols)
                throw DicomError("mixed image sizes");
        GeometryPlan plan = planGeometry(slices, h0.cols, h0.rows, "series " + si.key);
        si.dims = plan.dims;
        si.spacing = plan.spacing;
        for (auto& w : plan.warnings) si.warnings.push_back(std::move(w));
        ordered.clear();
        for (int k : plan.order) ordered.push_back(units[static_cast<std::size_t>(k)]);
    } catch (const DicomError& e) {
        if (cannot.empty()) cannot = e.what();
    }
    if (!cannot.empty()) {
        si.unloadableReason = cannot;
    }
    return ordered;
}

/** Files in slice order, with the frames each contributes when not all of them. */
void listFilesInSliceOrder(const std::vector<DicomHeader>& hs, const std::vector<Unit>& ordered,
                           DicomSeriesInfo& si) {
    std::unordered_map<int, std::size_t> fileIndex;
    std::vector<int> fileHeader;
    for (const Unit& u : ordered) {
        auto [it, inserted] = fileIndex.try_emplace(u.h, si.files.size());
        if (inserted) {
            si.files.push_back(hs[static_cast<std::size_t>(u.h)].path);
            si.frames.emplace_back();
            fileHeader.push_back(u.h);
        }
        si.frames[it->second].push_back(u.f);
    }
    bool anyPartial = false;
    for (std::size_t k = 0; k < si.frames.size(); ++k) {
        auto& fr = si.frames[k];
        std::sort(fr.begin(), fr.end());
        if (std::int64_t(fr.size()) == hs[static_cast<std::size_t>(fileHeader[k])].frames)
            fr.clear();
        else
            anyPartial = true;
    }
    if (!anyPartial) si.frames.clear();
    si.imageCount = int(si.files.size());
}

/** Series `g` of the group `groupKey` whose hard split (by `splitReason`) and duplicate
 *  resolution gave `parts`. */
DicomSeriesInfo describeSeries(const std::vector<DicomHeader>& hs, const std::string& groupKey,
                               const std::vector<Part>& parts, std::size_t g,
                               const std::string& splitReason) {
    const Part& part = parts[g];
    const DicomHeader& h0 = hs[static_cast<std::size_t>(part.units[0].h)];
    std::string why = splitReason;
    if (!part.note.empty()) why += (why.empty() ? "" : ", ") + part.note;
    DicomSeriesInfo si = seriesIdentity(h0, groupKey, g, parts.size(), why);
    si.frameCount = int(part.units.size());
    const std::vector<Unit> ordered = planSeries(hs, part.units, si);
    listFilesInSliceOrder(hs, ordered, si);
    return si;
}

} // namespace

std::string sliceLabel(const DicomHeader& h, std::int64_t frame) {
    std::string s = h.path.filename().string();
    if (h.frames > 1) s += " frame " + std::to_string(frame + 1);
    return s;
}

std::vector<DicomSeriesInfo> groupIntoSeries(const std::vector<DicomHeader>& hs,
                                             std::vector<std::string>& skipped) {
    std::vector<DicomSeriesInfo> out;
    for (const PrimaryGroup& group : groupBySeriesUid(hs, uniqueInstances(hs, skipped))) {
        const HardSplit hard = splitByImageGeometry(hs, unitsOf(hs, group.members));
        const std::vector<Part> parts = splitDuplicates(hs, hard.parts);
        for (std::size_t g = 0; g < parts.size(); ++g)
            out.push_back(describeSeries(hs, group.key, parts, g, hard.reason));
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const DicomSeriesInfo& a, const DicomSeriesInfo& b) {
                         if (a.studyUid != b.studyUid) return a.studyUid < b.studyUid;
                         return a.key < b.key;
                     });
    return out;
}

} // namespace dicom_detail

namespace {

/** The files the folder's DICOMDIR lists; nullopt when it has none or it cannot be read (noted in
 *  `skipped`: then every file in the folder is scanned). */
std::optional<std::vector<fs::path>> filesListedInDicomdir(const fs::path& folder,
                                                           std::vector<std::string>& skipped) {
    std::error_code ec;
    const auto dicomdir = findCaseInsensitive(folder, "DICOMDIR");
    if (!dicomdir || !fs::is_regular_file(*dicomdir, ec)) return std::nullopt;
    std::string why;
    auto refs = filesFromDicomdir(*dicomdir, skipped, why);
    if (!refs) {
        skipped.push_back(dicomdir->string() + ": unreadable DICOMDIR (" + why +
                          "); every file in the folder was scanned instead");
        return std::nullopt;
    }
    if (refs->empty()) skipped.push_back(dicomdir->string() + ": lists no files");
    return refs;
}

/** Every regular file below `folder`. Others that are not folders (FIFOs, sockets, devices:
 *  opening a FIFO blocks until a writer comes) are not opened: they go to `special`. */
std::vector<fs::path> walkFolder(const fs::path& folder, std::vector<std::string>& skipped,
                                 std::vector<fs::path>& special, const CancelToken* cancel) {
    std::vector<fs::path> files;
    std::error_code ec;
    std::int64_t count = 0;
    fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, ec);
    if (ec) throw DicomError(folder.string() + ": cannot list folder: " + ec.message());
    for (const fs::recursive_directory_iterator end; it != end; it.increment(ec)) {
        if (ec) {
            skipped.push_back(folder.string() + ": listing stopped: " + ec.message());
            break;
        }
        if ((++count & 255) == 0) checkCancel(cancel);
        std::error_code fec;
        const fs::file_status st = it->status(fec); // stat(2), following links
        if (fs::is_regular_file(st))
            files.push_back(it->path());
        else if (!fec && fs::exists(st) && !fs::is_directory(st))
            special.push_back(it->path());
    }
    return files;
}

/** The files to scan, sorted: `folder` itself when it is a file, else those its DICOMDIR lists,
 *  else every file below it. */
std::vector<fs::path> filesToScan(const fs::path& folder, std::vector<std::string>& skipped,
                                  std::vector<fs::path>& special, const CancelToken* cancel) {
    std::error_code ec;
    std::vector<fs::path> files;
    if (fs::is_regular_file(folder, ec)) {
        files.push_back(folder);
    } else if (fs::is_directory(folder, ec)) {
        if (auto listed = filesListedInDicomdir(folder, skipped))
            files = std::move(*listed);
        else
            files = walkFolder(folder, skipped, special, cancel);
    } else {
        throw DicomError(folder.string() + ": not a folder or file");
    }
    std::sort(files.begin(), files.end());
    return files;
}

/** Why a file gave no header, and what kind of file it is. */
struct HeaderFailure {
    enum Kind { Broken, NotDicom, NoImage };
    std::string message;
    Kind kind = Broken;
    std::string sopClass; ///< NoImage: its SOP class in words
};

/** `file` as the user knows it: relative to the scanned folder (its name when that fails). */
std::string shortName(const fs::path& file, const fs::path& folder) {
    const fs::path rel = file.lexically_relative(folder);
    if (rel.empty() || rel == "." || *rel.begin() == "..") return file.filename().string();
    return rel.generic_string();
}

/** "skipped 2 files that are not DICOM: a, b": the count and the first three names. */
std::string skipSummary(const std::vector<std::string>& names, const char* one, const char* many) {
    std::string s =
        "skipped " + std::to_string(names.size()) + " " + (names.size() == 1 ? one : many) + ": ";
    for (std::size_t k = 0; k < std::min<std::size_t>(3, names.size()); ++k)
        s += (k ? ", " : "") + names[k];
    if (names.size() > 3) s += " and " + std::to_string(names.size() - 3) + " more";
    return s;
}

/** Each failure in `skipped` (file order); files that are not DICOM, and DICOM objects without
 *  an image, summed up once each in `warnings`. */
void reportFailures(const fs::path& folder, const std::vector<fs::path>& files,
                    const std::vector<HeaderFailure>& failures, DicomScanResult& result) {
    std::vector<std::string> notDicom, noImage;
    for (std::size_t k = 0; k < files.size(); ++k) {
        const HeaderFailure& f = failures[k];
        if (f.message.empty()) continue;
        result.skipped.push_back(f.message);
        if (f.kind == HeaderFailure::NotDicom) notDicom.push_back(shortName(files[k], folder));
        if (f.kind == HeaderFailure::NoImage)
            noImage.push_back(shortName(files[k], folder) + " (" + f.sopClass + ")");
    }
    if (!notDicom.empty())
        result.warnings.push_back(
            skipSummary(notDicom, "file that is not DICOM", "files that are not DICOM"));
    if (!noImage.empty())
        result.warnings.push_back(
            skipSummary(noImage, "DICOM file without an image", "DICOM files without an image"));
}

/** FIFOs, sockets and devices in the folder: each in `skipped`, and one warning naming them. */
void reportSpecialFiles(const fs::path& folder, std::vector<fs::path>& special,
                        DicomScanResult& result) {
    if (special.empty()) return;
    std::sort(special.begin(), special.end());
    std::vector<std::string> names;
    for (const fs::path& p : special) {
        result.skipped.push_back(p.string() +
                                 ": not a regular file (FIFO, socket or device), not read");
        names.push_back(shortName(p, folder));
    }
    result.warnings.push_back(skipSummary(names, "file that is not a regular file (not read)",
                                          "files that are not regular files (not read)"));
}

/** The headers of `files`, read in parallel; why the others are no DICOM images goes to the
 *  result's `skipped` and `warnings` (see reportFailures). */
std::vector<DicomHeader> readHeaders(const fs::path& folder, const std::vector<fs::path>& files,
                                     DicomScanResult& result, const ProgressFn& progress,
                                     const CancelToken* cancel) {
    std::vector<std::optional<DicomHeader>> headers(files.size());
    std::vector<HeaderFailure> failures(files.size());
    {
        Progress prog(progress, "reading DICOM headers", 0.0, 0.95, std::int64_t(files.size()));
        ThreadPool pool;
        runParallel(pool, std::int64_t(files.size()), 4, [&](std::int64_t i) {
            checkCancel(cancel);
            const auto k = static_cast<std::size_t>(i);
            try {
                headers[k] = readHeader(files[k]);
            } catch (const NotDicomError& err) {
                failures[k] = {err.what(), HeaderFailure::NotDicom, {}};
            } catch (const NoImageError& err) {
                failures[k] = {err.what(), HeaderFailure::NoImage, err.sopClass};
            } catch (const DicomError& err) {
                failures[k] = {err.what(), HeaderFailure::Broken, {}};
            } catch (const std::exception& err) {
                failures[k] = {files[k].string() + ": " + err.what(), HeaderFailure::Broken, {}};
            }
            prog.step();
        });
        prog.finish();
    }
    reportFailures(folder, files, failures, result);
    std::vector<DicomHeader> usable;
    for (std::size_t k = 0; k < files.size(); ++k)
        if (headers[k]) usable.push_back(std::move(*headers[k]));
    return usable;
}

/** The error when no series was found: the file count and the first three reasons to skip. */
std::string noSeriesMessage(const fs::path& folder, std::size_t fileCount,
                            const std::vector<std::string>& skipped) {
    std::string msg = folder.string() + ": no DICOM image series found (" +
                      std::to_string(fileCount) + (fileCount == 1 ? " file" : " files");
    if (!skipped.empty()) {
        msg += "; e.g. ";
        for (std::size_t k = 0; k < std::min<std::size_t>(3, skipped.size()); ++k)
            msg += (k ? "; " : "") + skipped[k];
    }
    return msg + ")";
}

} // namespace

DicomScanResult scanDicomFolder(const std::filesystem::path& folder, const ProgressFn& progress,
                                const CancelToken* cancel) {
    initDcmtk();
    DicomScanResult result;
    std::error_code ec;
    if (!fs::exists(folder, ec)) throw DicomError(folder.string() + ": folder not found");
    std::vector<fs::path> special;
    const std::vector<fs::path> files = filesToScan(folder, result.skipped, special, cancel);
    reportSpecialFiles(folder, special, result);
    std::vector<DicomHeader> usable = readHeaders(folder, files, result, progress, cancel);
    checkCancel(cancel);
    result.series = groupIntoSeries(usable, result.skipped);
    if (progress) progress(1.0, "reading DICOM headers");
    if (result.series.empty())
        throw DicomError(noSeriesMessage(folder, files.size(), result.skipped));
    return result;
}

} // namespace fvr::core
