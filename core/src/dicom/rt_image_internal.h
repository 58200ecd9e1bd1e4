#pragma once
// The RT Image reader that readXrayGeometry calls (rt_image_geometry.cpp), and the element
// readers both take from xray_geometry.cpp. Not installed.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/dicom/xray_geometry.h>

namespace fvr::core::dicom_detail {

/** "DistanceSourceToDetector (0018,1110)". */
std::string tagText(const DcmTagKey& tag);
/** A number for a message ("%.6g"). */
std::string num(double v);
/** The element's value as text, trimmed; empty when absent. */
std::string stringOf(DcmItem* item, const DcmTagKey& tag);
/** Every value of a numeric element (DS, IS, FL, FD); empty when absent or empty. Throws naming
 *  the file and the tag when a value is not a finite number. */
std::vector<double> numbersOf(DcmItem* item, const DcmTagKey& tag,
                              const std::filesystem::path& file);

/** Fills `g` (file, width and height set) with an RT Image's beams and imager cameras, one per
 *  frame, its pitch, principal offset and isocentre, and a warning for each value assumed.
 *  Throws DicomError naming the file and the tag. */
void readRtImageGeometry(XrayGeometry& g, DcmDataset* ds, std::int64_t frames);

} // namespace fvr::core::dicom_detail
