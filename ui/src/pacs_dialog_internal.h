#pragma once
// What the PACS dialog's source files share: the data roles and columns of its lists.
#include <QString>

#include <string>

namespace fvr::ui::pacs_dialog {

enum Role {
    kStudyUid = Qt::UserRole,
    kSeriesUid,
    kSeriesLoaded,
    kFolder,
    kComplete,
    kIncoming, ///< Local studies: in the Incoming area (sent to the listener unasked)
    kSource ///< Local studies: the node it was retrieved from, "" when unknown
};
enum ResultColumn {
    kPatient,
    kPatientId,
    kDate,
    kDescription,
    kModalities,
    kSeries,
    kImages,
    kLocal ///< what the local store holds of it: complete, partial (n images), or nothing
};
inline QString text(const std::string& s) { return QString::fromStdString(s); }

} // namespace fvr::ui::pacs_dialog
