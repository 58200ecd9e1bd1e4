#pragma once
/** Projections as DICOM files (DCMTK), so they open in any viewer or PACS. */
#include <filesystem>
#include <string>

#include <cstdint>
#include <optional>
#include <vector>

#include <glm/mat3x3.hpp>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/render/projection.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** A display window in the values' units: centre and width (DICOM's C.11.2.1.2 linear window),
 *  and whether low values show bright. */
struct DisplayWindowValues {
    double centre = 0.0, width = 1.0;
    bool inverted = false;
};

/** An overlay plane (group 6000) over the image: graphics and text as a bitmap that viewers show
 *  over the image and can hide, leaving the pixel values untouched (annotations). */
struct DicomOverlay {
    std::vector<std::uint8_t> bits; ///< rows x cols, row-major, nonzero: on; empty: no overlay
    std::string description; ///< OverlayDescription, e.g. "annotations"
};

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
    /** The source's study time, ID, description, accession number, referring physician, the
     *  patient's sex and birth date, and its manufacturer: copied, empty when unknown (type 2). */
    DicomStudyFields study;
    /** Index frame -> patient (LPS) of the rendered volume, when its orientation is known: the
     *  Secondary Capture then says PatientOrientation (the patient directions of its rows and
     *  columns); without it PatientOrientation is written empty (type 2C, unknown). */
    std::optional<glm::dmat3> patientDirection;
    /** The window the user sees, in the written values' units (WindowCenter/WindowWidth); unset:
     *  the full range of the values. `windowInverted`: bright for low values (MONOCHROME1). */
    std::optional<DisplayWindowValues> window;
    /** The series this image belongs to: a new UID and number (newExportSeriesNumber) when empty
     *  / 0, so that each export is a series of its own; images of one export share both and
     *  count `instanceNumber` from 1. */
    std::string seriesInstanceUid;
    int seriesNumber = 0;
    int instanceNumber = 1;
    /** Written as overlay plane 6000 (the image's size) when not empty. */
    DicomOverlay overlay;
};

/** A SeriesNumber for a new export: the UTC time of day as HHMMSS (readable: "series 143205" was
 *  made at 14:32:05), one more than the last one this process gave when that is not larger. */
int newExportSeriesNumber();

/** A new SeriesInstanceUID (DCMTK's generator under its site root). */
std::string newSeriesInstanceUid();

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
