#pragma once
/** How a path becomes a volume: the one rule fvr-render and the workstation follow (which kind
 *  of input a path names, when values without units are taken for Hounsfield units; which DICOM
 *  series opens by default is dicom.h's defaultSeriesIndex). */
#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/io/volume_io.h>
#include <fvr/core/render/preprocess.h> // ProgressFn, CancelToken
#include <fvr/core/volume.h>

namespace fvr::core {

enum class InputKind {
    Phantom, ///< "phantom:chest[:N]" or "phantom:shepp-logan[:N]": a built-in phantom, N^3 voxels
    DicomFolder, ///< a folder (scanned recursively; its DICOMDIR is read when present)
    DicomFile, ///< one DICOM file (single image or multi-frame)
    VolumeFile, ///< .mhd, .mha, .nii, .nii.gz (or a headerless raw file with a RawSpec)
};

/** The built-in phantoms: makeChestPhantomVolume, makeSheppLoganVolume (xray/phantom.h). */
enum class PhantomKind { SheppLogan, Chest };

/** What an input names. */
struct InputSource {
    InputKind kind = InputKind::Phantom;
    std::filesystem::path path; ///< the folder or file (a DICOMDIR names its folder)
    int phantomSize = 128; ///< Phantom: voxels per axis (default 128 Shepp-Logan, 160 chest)
    PhantomKind phantom = PhantomKind::SheppLogan; ///< Phantom: which one
};

/**
 * The rule, in this order: "phantom:chest[:N]" and "phantom:shepp-logan[:N]" are the built-in
 * phantoms (N voxels per axis, default 160 for the chest, 128 for Shepp-Logan; the size is
 * checked when it is built); a folder is a DICOM folder; a file named DICOMDIR
 * stands for its folder; a file with the DICM preamble is DICOM whatever its name; .mhd, .mha,
 * .nii and .nii.gz are volume files; .dcm, .dicom and names without extension are DICOM (old
 * files lack the preamble); anything else is a volume file (loadVolume then says which formats
 * it reads). Throws SettingsError for a bad phantom spec and LoadError naming the path when it
 * does not exist.
 */
InputSource classifyInput(const std::string& input);

/**
 * Values without stated units (NIfTI, MetaImage, raw) are taken for Hounsfield units when their
 * range looks like CT: the minimum in [-3100, -900] (air is -1000; some scanners pad with -3024)
 * and the maximum at least 200 (soft tissue and bone). Changes `volume.units` only when they are
 * Unknown and the range fits; returns the warning to show then.
 */
std::optional<std::string> guessHounsfieldUnits(Volume& volume);

/**
 * Voxels that are not finite (NaN, ±inf: masked regions of a NIfTI, a broken file) would spread
 * through the 3D transform into a large part of every projection. They become the lowest finite
 * value of the volume (air in a CT; 0 when none is finite), and the warning says how many.
 * Returns nothing when every voxel is finite. openStudy and fvr.Volume call it.
 */
std::optional<std::string> replaceNonFiniteVoxels(Volume& volume);

struct OpenOptions {
    std::string seriesKey; ///< DICOM folder: the series to open (empty: the default)
    std::optional<RawSpec> raw; ///< VolumeFile: read as headerless raw with this geometry
    /** DICOM folder: a scan of the same folder made before (the workstation scans first to let
     *  the user choose); null: scan now. */
    std::shared_ptr<const DicomScanResult> scan;
};

struct OpenedStudy {
    Volume volume;
    /** Which series was opened and why, the loader's warnings, the scan's warnings for the
     *  series, the Hounsfield guess and an orientation assumed; each once. */
    std::vector<std::string> warnings;
    /** DICOM inputs: the series opened (patient and study for exports). */
    std::optional<DicomSeriesInfo> series;
};

/**
 * Opens `source` by the rule above: the phantom, a volume file, a DICOM file or a folder's
 * series (OpenOptions::seriesKey, else defaultSeriesIndex), then replaceNonFiniteVoxels and
 * guessHounsfieldUnits. Progress
 * covers scan and load; throws LoadError/DicomError/SettingsError naming the file and the
 * problem, Cancelled when cancelled.
 */
OpenedStudy openStudy(const InputSource& source, const OpenOptions& options = {},
                      const ProgressFn& progress = {}, const CancelToken* cancel = nullptr);

} // namespace fvr::core
