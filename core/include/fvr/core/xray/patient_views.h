#pragma once
/** Patient-oriented views and labels from the volume's direction cosines (DICOM LPS: +x = patient
 *  left, +y = posterior, +z = superior). Views are cameras: "AP" looks from anterior to
 *  posterior, head up, so the patient's left is on the image's right (the radiograph convention);
 *  "PA" looks from posterior to anterior (the patient's left on the image's left); "LEFT" looks
 *  from the patient's left side, "RIGHT" from the right; "HEAD" looks from above towards the feet
 *  (anterior up); "FEET" looks from the feet towards the head, anterior up, patient's left on the
 *  image's right (the axial CT display convention). */
#include <string>

#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>

namespace fvr::core {

enum class PatientView { AP, PA, Left, Right, Head, Feet };

const char* patientViewName(PatientView v); ///< "AP", "PA", "LEFT", "RIGHT", "HEAD", "FEET"
PatientView parsePatientView(const std::string& s); ///< case-insensitive; throws SettingsError

/** The view frame (in the volume's index frame) for a patient view. Throws SettingsError when
 *  the direction cosines are degenerate. */
ViewFrame patientViewFrame(const Volume& volume, PatientView view);
/** The same view of the patient in another volume's index frame (a prior beside the current
 *  study): `frame`'s axes, in `from`'s index frame, turned into the patient's LPS directions and
 *  back into `to`'s. Storage order, obliqueness and mirroring (a determinant of -1) differ
 *  between studies; the patient directions on screen stay the same. */
ViewFrame transferViewFrame(const Volume& from, const Volume& to, const ViewFrame& frame);

/** Patient-direction label of a direction given in the volume's index frame, e.g. "L", "A",
 *  "LA" (dominant first; components under ~20% of the largest are left out). */
std::string patientDirectionLabel(const Volume& volume, const Vec3& indexFrameDirection);

} // namespace fvr::core
