// The one rule for opening a path (classifyInput, the default series, the Hounsfield guess) and
// openStudy, which follows it for every front end.
#include <fvr/core/io/open_study.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>
#include <fvr/core/xray/phantom.h>

namespace fvr::core {
namespace fs = std::filesystem;

namespace {

InputSource parsePhantom(const std::string& spec) {
    const std::string rest = spec.substr(std::string("phantom:").size());
    const auto colon = rest.find(':');
    const std::string kind = rest.substr(0, colon);
    InputSource s;
    s.kind = InputKind::Phantom;
    if (kind == "chest") {
        s.phantom = PhantomKind::Chest;
        s.phantomSize = 160;
    } else if (kind == "shepp-logan") {
        s.phantom = PhantomKind::SheppLogan;
        s.phantomSize = 128;
    } else {
        throw SettingsError("INPUT: unknown phantom '" + kind +
                            "' (expected phantom:chest[:N] or phantom:shepp-logan[:N])");
    }
    if (colon != std::string::npos) {
        const std::string n = rest.substr(colon + 1);
        const auto size = parseNumber<int>(n);
        if (!size) throw SettingsError("phantom size: expected an integer, found '" + n + "'");
        s.phantomSize = *size;
    }
    return s;
}

/** What a file that is neither regular nor a folder is, in words. */
const char* specialFileKind(fs::file_type t) {
    switch (t) {
    case fs::file_type::fifo: return "a FIFO (named pipe)";
    case fs::file_type::socket: return "a socket";
    case fs::file_type::character: return "a character device";
    case fs::file_type::block: return "a block device";
    default: return "not a regular file";
    }
}

bool hasDicomPreamble(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    char magic[4] = {};
    in.seekg(128);
    return in.read(magic, 4) && std::string(magic, 4) == "DICM";
}

OpenedStudy openDicomFolder(const InputSource& source, const OpenOptions& options,
                            const ProgressFn& progress, const CancelToken* cancel) {
    auto scan = options.scan;
    ProgressFn loading = progress;
    if (!scan) {
        auto part = [&](double from, double to) -> ProgressFn {
            if (!progress) return {};
            return
                [=](double f, std::string_view stage) { progress(from + (to - from) * f, stage); };
        };
        scan = std::make_shared<const DicomScanResult>(
            scanDicomFolder(source.path, part(0.0, 0.4), cancel));
        loading = part(0.4, 1.0);
    }
    OpenedStudy study;
    const DicomSeriesInfo* chosen = nullptr;
    DicomVolume loaded =
        loadChosenSeries(*scan, options.seriesKey, source.path, loading, cancel, &chosen);
    study.volume = std::move(loaded.volume);
    study.warnings = std::move(loaded.warnings);
    study.series = *chosen;
    return study;
}

} // namespace

InputSource classifyInput(const std::string& input) {
    // A C string (every system call) would end at the NUL and open another file.
    refuseNul(input, "INPUT: the path");
    if (input.rfind("phantom:", 0) == 0) return parsePhantom(input);
    InputSource s;
    s.path = fs::path(input);
    std::error_code ec;
    // fs::status is stat(2): it follows links and never opens the file. Opening a FIFO blocks
    // until a writer appears, and a device can stream forever: only regular files and folders
    // are inputs.
    const fs::file_status st = fs::status(s.path, ec);
    if (ec || !fs::exists(st)) throw LoadError(input + ": no such file or folder");
    if (!fs::is_directory(st) && !fs::is_regular_file(st))
        throw LoadError(input + ": " + specialFileKind(st.type()) +
                        ", not a regular file: the inputs are files, folders and phantoms, and "
                        "this one is not read (it could block or never end)");
    if (fs::is_directory(st)) {
        s.kind = InputKind::DicomFolder;
    } else if (iequals(s.path.filename().string(), "dicomdir")) {
        s.kind = InputKind::DicomFolder;
        s.path = s.path.has_parent_path() ? s.path.parent_path() : fs::path(".");
    } else if (hasDicomPreamble(s.path)) {
        s.kind = InputKind::DicomFile;
    } else if (isVolumeFileName(s.path)) {
        s.kind = InputKind::VolumeFile;
    } else {
        // DICOM by name (.dcm, .dicom, no extension: old files lack the preamble); anything
        // else is a volume file, and loadVolume says which formats it reads.
        const std::string ext = asciiLower(s.path.extension().string());
        s.kind = ext == ".dcm" || ext == ".dicom" || ext.empty() ? InputKind::DicomFile
                                                                 : InputKind::VolumeFile;
    }
    return s;
}

std::optional<std::string> replaceNonFiniteVoxels(Volume& volume) {
    std::size_t bad = 0;
    float lowest = std::numeric_limits<float>::infinity();
    for (float v : volume.voxels) {
        if (!std::isfinite(v))
            ++bad;
        else
            lowest = std::min(lowest, v);
    }
    if (bad == 0) return std::nullopt;
    if (!std::isfinite(lowest)) lowest = 0.0f;
    for (float& v : volume.voxels)
        if (!std::isfinite(v)) v = lowest;
    std::ostringstream w;
    w << bad << " of " << volume.voxels.size()
      << " voxels are not finite (NaN or infinite); they are rendered as " << lowest
      << ", the lowest finite value";
    return w.str();
}

std::optional<std::string> guessHounsfieldUnits(Volume& volume) {
    if (volume.units != ValueUnits::Unknown) return std::nullopt;
    const auto [lo, hi] = volume.valueRange();
    if (!(lo <= -900.0f && lo >= -3100.0f && hi >= 200.0f)) return std::nullopt;
    volume.units = ValueUnits::HounsfieldUnits;
    std::ostringstream w;
    w << "The file states no units; its values (" << lo << " … " << hi
      << ") look like Hounsfield units and are treated as such.";
    return w.str();
}

OpenedStudy openStudy(const InputSource& source, const OpenOptions& options,
                      const ProgressFn& progress, const CancelToken* cancel) {
    OpenedStudy study;
    switch (source.kind) {
    case InputKind::Phantom:
        if (progress) progress(0.05, "building phantom");
        study.volume = source.phantom == PhantomKind::Chest
                           ? makeChestPhantomVolume(source.phantomSize)
                           : makeSheppLoganVolume(source.phantomSize);
        break;
    case InputKind::VolumeFile:
        if (progress) progress(0.05, "reading file");
        study.volume = options.raw ? loadRaw(source.path, *options.raw) : loadVolume(source.path);
        break;
    case InputKind::DicomFile: {
        if (options.raw) { // headerless raw data whatever its name
            if (progress) progress(0.05, "reading file");
            study.volume = loadRaw(source.path, *options.raw);
            break;
        }
        if (progress) progress(0.05, "reading DICOM file");
        DicomVolume loaded = loadDicomFile(source.path);
        study.volume = std::move(loaded.volume);
        study.warnings = std::move(loaded.warnings);
        break;
    }
    case InputKind::DicomFolder: study = openDicomFolder(source, options, progress, cancel); break;
    }
    if (cancel) cancel->check();
    if (auto w = replaceNonFiniteVoxels(study.volume)) study.warnings.push_back(*w);
    if (auto w = guessHounsfieldUnits(study.volume)) study.warnings.push_back(*w);
    if (!study.volume.orientationStated)
        study.warnings.push_back(
            "The file states no orientation: its axes are assumed to point to the patient's "
            "left (x), posterior (y) and superior (z) (LPS); the orientation labels say so.");
    if (progress) progress(1.0, "study opened");
    return study;
}

} // namespace fvr::core
