#pragma once
// DICOM text in UTF-8: the values of an item converted from its SpecificCharacterSet (0008,0005)
// to UTF-8, so that every string the program keeps (index, sidecars, the UI, written objects) is
// UTF-8. Private to core (the DICOM reader and the PACS code share it).
#include <string>
#include <string_view>

class DcmItem;

namespace fvr::core::dicom_detail {

/** `text` as valid UTF-8: each byte that is not part of a well-formed UTF-8 sequence becomes
 *  U+FFFD. `replaced` (when given) says whether any did. */
std::string validUtf8(std::string_view text, bool* replaced = nullptr);

/** Converts the text values at the top level of `item` (VRs SH, LO, ST, LT, UT, UC, PN) from the
 *  character set `charset` (the value of SpecificCharacterSet, "" for the default repertoire) to
 *  UTF-8, in place, and sets the item's SpecificCharacterSet to "ISO_IR 192" when it had one.
 *  DCMTK's converter (iconv) does it; the ISO 2022 Japanese sets (IR 87 and IR 159 with ASCII),
 *  which this DCMTK build (over the C library's iconv) cannot open, through the C library's
 *  ISO-2022-JP-2. A value that cannot be converted (bytes that are not of its set, a set no
 *  converter knows, 8-bit bytes without a declared set) keeps its bytes where they are valid
 *  UTF-8, else gets U+FFFD for each bad byte. Returns those problems in words, naming the
 *  elements and the set ("" when every value converted); never throws. */
std::string convertTextToUtf8(DcmItem& item, const std::string& charset);

/** The same with the item's own SpecificCharacterSet. */
std::string convertTextToUtf8(DcmItem& item);

} // namespace fvr::core::dicom_detail
