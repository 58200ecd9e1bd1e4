#pragma once
/** Analytic ellipsoid phantoms: the embedded default study and the exact test oracle. */
#include <vector>

#include <fvr/core/render/projection.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** A solid ellipsoid, in mm relative to the volume's physical centre. `axes[i]` (column i of
 *  the rotation) is the unit direction of semi-axis i in the volume frame; `density` adds
 *  mu/mu_water inside. */
struct Ellipsoid {
    Vec3 centre{0, 0, 0};
    Vec3 semiAxes{1, 1, 1};
    glm::dmat3 axes{1.0};
    double density = 1.0;

    /** Length (mm) of the chord of the line o + t dir (dir unit, o relative to the centre). */
    double chord(const Vec3& o, const Vec3& dir) const;
    /** The parameters t0 < t1 where the line enters and leaves; false if it misses. */
    bool interval(const Vec3& o, const Vec3& dir, double& t0, double& t1) const;
    bool contains(const Vec3& p) const;
};

/**
 * Ellipsoids in mu relative to water (air 0). In Hounsfield units a voxel holds
 * HU = 1000 (mu - 1): -1000 wherever no ellipsoid is, inside the volume's box. Everything is
 * what lies inside the volume's box: the parts of an ellipsoid outside it are not imaged.
 */
class EllipsoidPhantom {
public:
    /** How overlapping ellipsoids combine. Sum: densities add (Shepp-Logan: negative densities
     *  carve). Paint: each point has the density of the last ellipsoid in the list that holds
     *  it (a later organ replaces what it overlaps, as anatomy does); line integrals stay exact:
     *  the density is constant between the points where the line crosses ellipsoid surfaces. */
    enum class Composition { Sum, Paint };

    std::vector<Ellipsoid> ellipsoids;
    Composition composition = Composition::Sum;

    /** 3D Shepp-Logan (Kak & Slaney intensities: skull 2.0 = +1000 HU, brain 1.02 = +20 HU,
     *  ventricles 1.0 = 0 HU, lesions 1.03 = +30 HU) scaled so the unit of the classic
     *  normalised coordinates is fieldMm / 2 mm. Geometry after the 3D table of Schabel's
     *  phantom3d with our own tilt convention (rotation about z by phi, then about x by psi). */
    static EllipsoidPhantom sheppLogan3D(double fieldMm);

    /**
     * An adult human chest (Paint composition) in the volume frame LPS: +x the patient's left,
     * +y posterior, +z superior, mm from the volume's centre; built for a field (cube edge) of
     * 420 mm and scaled by fieldMm / 420. Its anatomy, in painting order: the torso (elliptic,
     * 340 x 220 mm, narrowing to the neck, fat 0.92 under 12 mm of skin and fat, muscle and
     * soft tissue 1.04), neck and shoulders; the two lungs (0.25, -750 HU; each two ellipsoids,
     * wider at the base, apices above the clavicles) with hilar vessels (blood 1.06) branching
     * into them; the trachea and main bronchi (air 0); the heart (1.06, 130 mm wide, two
     * thirds left of the midline, apex down, left and anterior); the aorta (1.06: ascending,
     * arch with the aortic knob left of the trachea, descending left of the spine); the
     * diaphragm domes (right higher, liver 1.06 below; the stomach's gas bubble under the left
     * dome); the spine C6 to L3 (T1 centred at z = +148 mm, 27 mm apart; vertebral bodies: cortical
     * shell 1.85 around cancellous bone 1.20, 6 mm discs 1.04 between, spinous and transverse
     * processes 1.5); 12 pairs of ribs (cortical bone averaged over the rib's section, 1.6), each a
     * chain of overlapping ellipsoids on an elliptic arc from its vertebra around the lung, sloping
     * down anteriorly (ribs 1-10 to the front, 11 and 12 floating); the sternum (1.35); the
     * clavicles (1.6); the scapulae (1.4) and the humeral heads (cancellous 1.3 in a 1.8
     * shell). Densities are mu/mu_water near 70 keV from ICRU Report 44 / ICRP 89 tissue
     * compositions (adipose 0.92-0.95, soft tissue 1.04, blood 1.06, inflated lung 0.26,
     * cancellous bone 1.1-1.3, cortical bone 1.85-1.9 relative to water); sizes are typical
     * adult values (Gray's Anatomy; chest radiograph norms: cardiothoracic ratio about 0.45).
     */
    static EllipsoidPhantom chest(double fieldMm = 420.0);

    /** Voxelises into HU: voxel centres at (i - (N-1)/2) s. Sum: each voxel the average over
     *  supersample^3 sub-points where an ellipsoid boundary crosses it (exact elsewhere).
     *  Paint: each voxel the mean over supersample^2 lines along x through it, each integrated
     *  exactly over the voxel's length. */
    Volume voxelize(const Dims3& dims, const Vec3& spacing, int supersample = 4) const;

    /** Exact line integrals for the same pixels as the renderers (see ViewFrame). Mu mapping:
     *  sum of density x chord (mm). Raw mapping (HU): -1000 x chord through the volume's box of
     *  extent N*s plus 1000 x sum of density x chord. With depthCue > 0 every chord is weighted
     *  by the depth cueing weight of xray.h (exactly: the weight is linear along the ray).
     *  The bone-enhanced mapping has no closed form here (SettingsError). */
    ProjectionImage project(const ViewFrame& view, const ImageGeometry& image, ValueMapping mapping,
                            const Dims3& dims, const Vec3& spacing, double depthCue = 0.0) const;
};

/** The built-in demo study: Shepp-Logan with N^3 voxels over a 256 mm field, in HU. */
Volume makeSheppLoganVolume(int n = 128);

/** The built-in chest phantom (EllipsoidPhantom::chest(420)) with N^3 voxels over a 420 mm
 *  field, in HU, orientation stated: index axes x, y, z = patient left, posterior, superior
 *  (LPS), so the patient views (AP, PA, LEFT, ...) are right. N in 8..1024. */
Volume makeChestPhantomVolume(int n = 160);

} // namespace fvr::core
