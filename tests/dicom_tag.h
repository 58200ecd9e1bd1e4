#pragma once
// A DICOM file's attribute as text, for tests that read back what was written (DCMTK).
#include <string>

#include <dcmtk/config/osconfig.h> // first DCMTK include
#include <dcmtk/dcmdata/dctk.h>

namespace fvr::test {

/** A string attribute of the DICOM file `path`, its values joined by backslashes; "" when
 *  absent, "<unreadable>" when the file does not load. */
inline std::string dicomTag(const std::string& path, const DcmTagKey& key) {
    DcmFileFormat ff;
    if (ff.loadFile(path.c_str()).bad()) return "<unreadable>";
    OFString v;
    ff.getDataset()->findAndGetOFStringArray(key, v);
    return v.c_str();
}

} // namespace fvr::test
