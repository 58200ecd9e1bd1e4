#pragma once
// What the DICOM writers share (dicom_export.cpp: the Secondary Capture of a parallel
// projection; xray_export.cpp: a cone-beam DRR as XA; rt_image_export.cpp: a treatment beam's
// DRR as RT Image): the 16-bit quantisation of float values and its pixel module, decimal
// strings, the identity of a new instance, and the error naming the file. Not installed.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <filesystem>
#include <functional>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/geometry/camera.h>

namespace fvr::core::dicom_write {

/** Throws WriteError naming the file and the problem: "<path>: <detail>". */
[[noreturn]] void failWrite(const std::filesystem::path& path, const std::string& detail);

/** Stored 16-bit values and the rescale that maps them back: value = stored x slope + lo, over
 *  the finite values (a value that is not finite is stored as lo). */
struct Quantized {
    std::vector<Uint16> stored;
    double slope = 1.0, lo = 0.0, hi = 0.0;
};
Quantized quantize(const std::vector<float>& pixels);

using PutTag = std::function<void(const DcmTagKey&, const std::string&)>;

/** Puts a string value into `dset`; WriteError naming the file and the tag when DCMTK refuses. */
PutTag putterFor(DcmDataset* dset, const std::filesystem::path& path);

/** Whether a DRR's camera is the one its geometry makes (`expected`): the same size, source and
 *  detector centre within 1e-6 x max(1, scale) mm (scale: the SID), u and v within 1e-6. An
 *  X-ray or RT Image carries only its own geometry, so the writers check before writing. */
bool sameCamera(const ConeCamera& expected, const ConeCamera& actual, int width, int height,
                double scale);

/** A decimal string (DS) of at most 16 characters holding as many digits of v as fit. */
std::string decimalString(double v);

/** The image pixel module of `q` (one 16-bit unsigned sample, rows x cols per frame, every
 *  frame in q.stored), its rescale back to the values, a window over them (LINEAR_EXACT for a
 *  width below 1, the only function that permits it: PS3.3 C.11.2.1.2) and the pixel data. */
void putPixels16(const PutTag& put, DcmDataset* dset, const Quantized& q, int rows, int cols,
                 const std::filesystem::path& path,
                 const std::optional<DisplayWindowValues>& window = std::nullopt);

/** WindowCenter/WindowWidth: `window` when given (the user's), else the full range of `q`;
 *  LINEAR_EXACT for a width below 1, the only function that permits it (PS3.3 C.11.2.1.2). */
void putWindow(const PutTag& put, const Quantized& q,
               const std::optional<DisplayWindowValues>& window);

/** The UTC time of day as HHMMSS. */
int seriesNumberNow();

/** What every object we write carries first: `sopClassUid` and a new instance UID, the export's
 *  study (a new one when it names none), its series (a new one when it names none) with its
 *  number and the instance number, the patient, the type 2 attributes `emptyType2` present and
 *  empty (dciodvfy), the source study's date, time, ID, accession number, referring physician
 *  and description, the patient's sex and birth date (type 2: empty when unknown), and the
 *  content's date and time: now, UTC. */
void putNewInstance(const PutTag& put, const char* sopClassUid, const DicomExportInfo& info,
                    std::initializer_list<DcmTagKey> emptyType2);

} // namespace fvr::core::dicom_write
