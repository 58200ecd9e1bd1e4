#include <fvr/core/xray/patient_views.h>

#include <algorithm>

#include <cmath>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {

const char* patientViewName(PatientView v) {
    switch (v) {
    case PatientView::AP: return "AP";
    case PatientView::PA: return "PA";
    case PatientView::Left: return "LEFT";
    case PatientView::Right: return "RIGHT";
    case PatientView::Head: return "HEAD";
    case PatientView::Feet: return "FEET";
    }
    return "?";
}

PatientView parsePatientView(const std::string& s) {
    for (PatientView v : {PatientView::AP, PatientView::PA, PatientView::Left, PatientView::Right,
                          PatientView::Head, PatientView::Feet})
        if (iequals(s, patientViewName(v))) return v;
    throw SettingsError("view: expected AP|PA|LEFT|RIGHT|HEAD|FEET, found '" + s + "'");
}

namespace {
/** LPS vector -> index-frame vector: components along the (orthonormal) index axes. */
Vec3 fromPatient(const Volume& v, const Vec3& lps) {
    return lps * v.direction; // transpose(direction) lps
}
} // namespace

ViewFrame patientViewFrame(const Volume& volume, PatientView view) {
    Vec3 d{0, 1, 0}, u{0, 0, 1};
    switch (view) {
    case PatientView::AP: d = {0, 1, 0}, u = {0, 0, 1}; break;
    case PatientView::PA: d = {0, -1, 0}, u = {0, 0, 1}; break;
    case PatientView::Left: d = {-1, 0, 0}, u = {0, 0, 1}; break;
    case PatientView::Right: d = {1, 0, 0}, u = {0, 0, 1}; break;
    case PatientView::Head: d = {0, 0, -1}, u = {0, -1, 0}; break;
    case PatientView::Feet: d = {0, 0, 1}, u = {0, -1, 0}; break;
    }
    ViewFrame f = ViewFrame::fromDirUp(fromPatient(volume, d), fromPatient(volume, u));
    // R must be D x U in the patient's (right-handed) frame. Index frames stored mirrored (a
    // direction matrix with determinant -1, e.g. NIfTI with qfac -1) need R = -(D x U) in index
    // coordinates, or the image would be mirrored.
    f.r = fromPatient(volume, glm::cross(d, u));
    return f;
}

ViewFrame transferViewFrame(const Volume& from, const Volume& to, const ViewFrame& frame) {
    const auto move = [&](const Vec3& v) { return fromPatient(to, from.direction * v); };
    ViewFrame f;
    f.d = move(frame.d);
    f.u = move(frame.u);
    f.r = move(frame.r); // not d x u: a mirrored volume's index frame is left-handed
    return f;
}

std::string patientDirectionLabel(const Volume& volume, const Vec3& v) {
    const Vec3 w = volume.direction * v; // the LPS direction
    const char pos[3] = {'L', 'P', 'S'}, neg[3] = {'R', 'A', 'I'};
    int order[3] = {0, 1, 2};
    std::sort(order, order + 3, [&](int a, int b) { return std::abs(w[a]) > std::abs(w[b]); });
    const double top = std::abs(w[order[0]]);
    std::string label;
    for (int i : order)
        if (top > 0 && std::abs(w[i]) >= 0.2 * top) label += w[i] > 0 ? pos[i] : neg[i];
    return label;
}

} // namespace fvr::core
