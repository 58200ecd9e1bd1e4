// A cine as Multi-frame Grayscale Word Secondary Capture.
#include <fvr/core/dicom/multiframe_export.h>

#include <dcmtk/dcmdata/dctk.h>

#include <cstdio>
#include <sstream>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>

#include "dicom_write_internal.h"

namespace fvr::core {

using dicom_write::failWrite;

namespace {

/** The frames' values one after another (one quantisation, one rescale for all). */
std::vector<float> allPixels(const std::filesystem::path& path,
                             const std::vector<ProjectionImage>& frames) {
    if (frames.empty()) failWrite(path, "no frames to export");
    const int W = frames[0].width, H = frames[0].height;
    std::vector<float> all;
    all.reserve(std::size_t(W) * H * frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const ProjectionImage& f = frames[i];
        if (f.width != W || f.height != H || f.pixels.size() != std::size_t(W) * H || W <= 0 ||
            H <= 0)
            failWrite(path, "frame " + std::to_string(i + 1) + " is " + std::to_string(f.width) +
                                " x " + std::to_string(f.height) + ", not " + std::to_string(W) +
                                " x " + std::to_string(H) + " like the first");
        all.insert(all.end(), f.pixels.begin(), f.pixels.end());
    }
    return all;
}

std::string commentsOf(const std::vector<ProjectionImage>& frames, const CineDescription& cine,
                       const DicomExportInfo& info) {
    const ViewFrame& v = frames[0].view;
    std::ostringstream c;
    c << "FVR parallel projection cine: " << frames.size() << " frames, " << cine.stepDegrees
      << " deg apart about the " << cine.axis << " axis; values: " << info.valueDescription
      << "; frame 1 dir " << v.d[0] << " " << v.d[1] << " " << v.d[2] << ", up " << v.u[0] << " "
      << v.u[1] << " " << v.u[2] << " (volume index frame)";
    return c.str();
}

} // namespace

void writeDicomMultiframe(const std::filesystem::path& path,
                          const std::vector<ProjectionImage>& frames, const CineDescription& cine,
                          const DicomExportInfo& info) {
    const std::vector<float> all = allPixels(path, frames);
    if (!(cine.frameTimeMs > 0.0)) failWrite(path, "the frame time must be positive");
    if (frames.size() > 65535) failWrite(path, "more than 65535 frames");
    const dicom_write::Quantized q = dicom_write::quantize(all);
    DcmFileFormat file;
    DcmDataset* ds = file.getDataset();
    const dicom_write::PutTag put = dicom_write::putterFor(ds, path);
    dicom_write::putNewInstance(put, UID_MultiframeGrayscaleWordSecondaryCaptureImageStorage, info,
                                {DCM_Laterality, DCM_PatientOrientation, DCM_StudyTime});
    put(DCM_Modality, "OT");
    put(DCM_ConversionType, "WSD");
    put(DCM_Manufacturer, info.study.manufacturer);
    put(DCM_SecondaryCaptureDeviceManufacturer, "FVR Workstation");
    put(DCM_SeriesDescription, info.seriesDescription);
    put(DCM_ImageType, "DERIVED\\SECONDARY\\PROJECTION");
    put(DCM_BurnedInAnnotation, "NO");
    // The IOD allows MONOCHROME2 only (an inverted window on screen is said in ImageComments).
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    put(DCM_PresentationLUTShape, "IDENTITY");
    // The Cine and Multi-frame modules: the frames are FrameTime apart.
    put(DCM_NumberOfFrames, std::to_string(frames.size()));
    put(DCM_FrameTime, dicom_write::decimalString(cine.frameTimeMs));
    if (ds->putAndInsertTagKey(DCM_FrameIncrementPointer, DCM_FrameTime).bad())
        failWrite(path, "cannot set DICOM tag FrameIncrementPointer");
    put(DCM_CineRate, std::to_string(std::max(1L, std::lround(1000.0 / cine.frameTimeMs))));
    put(DCM_PreferredPlaybackSequencing, "0"); // looping
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.8g\\%.8g", frames[0].pixelSize, frames[0].pixelSize);
    put(DCM_PixelSpacing, buf);
    put(DCM_ImageComments, commentsOf(frames, cine, info));
    dicom_write::putPixels16(put, ds, q, frames[0].height, frames[0].width, path, info.window);
    writeAtomically(path, [&](const std::filesystem::path& tmp) {
        const OFCondition st = file.saveFile(tmp.c_str(), EXS_LittleEndianExplicit);
        if (st.bad()) failWrite(path, st.text());
    });
}

} // namespace fvr::core
