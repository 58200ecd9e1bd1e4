#pragma once
/** A cine (frames of one rotation) as one multi-frame DICOM object, and the header of a DICOM
 *  file as rows for a tag browser. */
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/render/projection.h>

namespace fvr::core {

/** What the cine says about its frames. */
struct CineDescription {
    double frameTimeMs = 100.0; ///< FrameTime (0018,1063): the time between frames
    double stepDegrees = 10.0; ///< the rotation from one frame to the next
    std::string axis = "patient S-I"; ///< the axis turned about, in words (ImageComments)
};

/**
 * Writes Multi-frame Grayscale Word Secondary Capture: every frame 16-bit unsigned with one
 * RescaleSlope/Intercept over all frames (so a viewer shows the float values), NumberOfFrames,
 * FrameTime and FrameIncrementPointer = FrameTime (the Cine module), the source's patient and
 * study as writeDicomProjection does, the user's window, and the rotation in ImageComments.
 * PatientOrientation is empty (type 2): a turning view has no one orientation. The IOD allows
 * MONOCHROME2 only: an inverted window is said in ImageComments, not in the pixels. The frames must
 * all have one size. Throws WriteError naming the path.
 */
void writeDicomMultiframe(const std::filesystem::path& path,
                          const std::vector<ProjectionImage>& frames, const CineDescription& cine,
                          const DicomExportInfo& info = {});

/** One element of a DICOM header: "(0010,0010)", "PatientName", "PN", the value as text
 *  (binary values and long ones shortened, "<16384 bytes>"), and its nesting depth (0 at the top,
 *  1 inside a sequence item ...). A sequence has a row of its own (value "<n items>"). */
struct DicomTagRow {
    std::string tag, keyword, vr, value;
    int depth = 0;
};

/** The file meta information and the data set of `path`, in file order (sequences with their
 *  items' elements below them). Throws LoadError naming the file when it is not readable
 *  DICOM. */
std::vector<DicomTagRow> readDicomTags(const std::filesystem::path& path);

} // namespace fvr::core
