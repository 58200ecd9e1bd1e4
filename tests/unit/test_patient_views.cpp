#include <gtest/gtest.h>

#include <fvr/core/errors.h>
#include <fvr/core/xray/patient_views.h>

using namespace fvr::core;

TEST(PatientViews, ApOnAnAxialStack) {
    Volume v; // identity direction: x = L, y = P, z = S (an axial stack as stored by DICOM)
    const ViewFrame f = patientViewFrame(v, PatientView::AP);
    EXPECT_EQ(patientDirectionLabel(v, f.d), "P"); // looking towards posterior
    EXPECT_EQ(patientDirectionLabel(v, f.u), "S"); // head up
    EXPECT_EQ(patientDirectionLabel(v, f.r), "L"); // patient's left on the image's right
    const ViewFrame feet = patientViewFrame(v, PatientView::Feet);
    EXPECT_EQ(patientDirectionLabel(v, feet.r), "L");
    EXPECT_EQ(patientDirectionLabel(v, feet.u), "A");
    EXPECT_EQ(patientDirectionLabel(v, patientViewFrame(v, PatientView::Left).r), "P");
    EXPECT_EQ(patientDirectionLabel(v, patientViewFrame(v, PatientView::Right).r), "A");
    EXPECT_EQ(patientDirectionLabel(v, patientViewFrame(v, PatientView::PA).r), "R");
}

TEST(PatientViews, CoronalStackAndObliqueLabels) {
    Volume v; // coronal: columns along L, rows along -S (down), slices along A
    v.direction = {Vec3{1, 0, 0}, Vec3{0, 0, -1}, Vec3{0, -1, 0}};
    const ViewFrame f = patientViewFrame(v, PatientView::AP);
    // Whatever the storage order, the labels stay true to the patient.
    EXPECT_EQ(patientDirectionLabel(v, f.d), "P");
    EXPECT_EQ(patientDirectionLabel(v, f.u), "S");
    EXPECT_EQ(patientDirectionLabel(v, f.r), "L");
    EXPECT_NEAR(f.d[2], -1.0, 1e-12); // posterior = -slice axis
    // index +z is anterior here, so -z is posterior: (1, 0, -0.5) is mostly left, then posterior.
    EXPECT_EQ(patientDirectionLabel(v, {1, 0, -0.5}), "LP");
    EXPECT_EQ(patientDirectionLabel(v, {0.05, 0, 1}), "A");
}

TEST(PatientViews, MirroredStorageIsNotShownMirrored) {
    Volume v; // radiological storage: index x runs to the patient's right (det = -1)
    v.direction = {Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    const ViewFrame f = patientViewFrame(v, PatientView::AP);
    EXPECT_EQ(patientDirectionLabel(v, f.r), "L");
    EXPECT_EQ(patientDirectionLabel(v, f.u), "S");
    // Trackball rotations keep the frame's handedness.
    const ViewFrame g = f.rotated(f.u, 0.3);
    EXPECT_LT(glm::dot(g.r, glm::cross(g.d, g.u)), 0.0);
}

TEST(PatientViews, Parse) {
    EXPECT_EQ(parsePatientView("ap"), PatientView::AP);
    EXPECT_EQ(parsePatientView("FEET"), PatientView::Feet);
    EXPECT_THROW(parsePatientView("lateral"), SettingsError);
}

TEST(PatientViews, AViewTransfersToAnotherStudyAsTheSamePatientView) {
    Volume axial; // identity: x = L, y = P, z = S
    Volume coronal; // columns along L, rows along -S, slices along A
    coronal.direction = {Vec3{1, 0, 0}, Vec3{0, 0, -1}, Vec3{0, -1, 0}};
    Volume mirrored; // index x runs to the patient's right (det = -1)
    mirrored.direction = {Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    const Volume* volumes[] = {&axial, &coronal, &mirrored};
    for (const Volume* from : volumes)
        for (const Volume* to : volumes)
            for (PatientView pv : {PatientView::AP, PatientView::PA, PatientView::Left,
                                   PatientView::Right, PatientView::Head, PatientView::Feet}) {
                const ViewFrame t = transferViewFrame(*from, *to, patientViewFrame(*from, pv));
                const ViewFrame want = patientViewFrame(*to, pv);
                EXPECT_LT(glm::length(t.d - want.d), 1e-12);
                EXPECT_LT(glm::length(t.u - want.u), 1e-12);
                EXPECT_LT(glm::length(t.r - want.r), 1e-12);
                // The labels on screen say the same in both.
                EXPECT_EQ(patientDirectionLabel(*to, t.r),
                          patientDirectionLabel(*from, patientViewFrame(*from, pv).r));
            }
    // An oblique turn (not a patient view) keeps its patient direction too.
    const ViewFrame ap = patientViewFrame(axial, PatientView::AP);
    const ViewFrame turned = ap.rotated(ap.u, 0.3).rotated(ap.r, -0.2);
    const ViewFrame t = transferViewFrame(axial, mirrored, turned);
    EXPECT_LT(glm::length(mirrored.direction * t.d - axial.direction * turned.d), 1e-12);
    EXPECT_LT(glm::length(mirrored.direction * t.r - axial.direction * turned.r), 1e-12);
}
