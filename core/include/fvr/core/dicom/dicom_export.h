#pragma once
/** Projections as DICOM files (DCMTK), so they open in any viewer or PACS. */
#include <filesystem>
#include <string>

#include <optional>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** What the exported image says about where it comes from. */
struct DicomExportInfo {
    std::string patientName, patientId, studyInstanceUid; ///< copied from the source when known
    std::string seriesDescription = "FVR projection";
    std::string valueDescription = "line integral"; ///< e.g. "mm (mu/mu_water x mm)"
    /** The source study's StudyDate (YYYYMMDD), copied with its UID so that the export does not
     *  contradict its study; empty when unknown (then written empty, as type 2 allows). */
    std::string studyDate;
    /** The pixels are transmitted intensities (Beer-Lambert), not line integrals: an X-ray
     *  image then says PixelIntensityRelationship LIN instead of LOG. */
    bool transmission = false;
};

/** Patient, patient ID, study UID and study date of the series a projection comes from (none for
 *  a phantom or a volume file): the export joins the source's study in a PACS. */
DicomExportInfo exportInfoFor(const std::optional<DicomSeriesInfo>& series);

/**
 * Writes a Secondary Capture image (MONOCHROME2, 16-bit unsigned stored values with
 * RescaleSlope/RescaleIntercept mapping them back to the float values, so a viewer shows the
 * real line integrals), PixelSpacing = the image's pixel size, and the view geometry (direction,
 * up, right in the volume frame) in ImageComments. Written to a temporary file and renamed.
 * Throws WriteError naming the path.
 */
void writeDicomProjection(const std::filesystem::path& path, const ProjectionImage& image,
                          const DicomExportInfo& info = {});

} // namespace fvr::core
