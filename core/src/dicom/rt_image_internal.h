#pragma once
// The RT Image reader that readXrayGeometry calls (rt_image_geometry.cpp). Not installed.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <cstdint>

#include <fvr/core/dicom/xray_geometry.h>

namespace fvr::core::dicom_detail {

/** Fills `g` (file, width and height set) with an RT Image's beams and imager cameras, one per
 *  frame, its pitch, principal offset and isocentre, and a warning for each value assumed.
 *  Throws DicomError naming the file and the tag. */
void readRtImageGeometry(XrayGeometry& g, DcmDataset* ds, std::int64_t frames);

} // namespace fvr::core::dicom_detail
