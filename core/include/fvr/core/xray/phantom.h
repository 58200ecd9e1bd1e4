#pragma once
/** Analytic ellipsoid phantoms: the embedded default study and the exact test oracle. */
#include <vector>

#include <fvr/core/render/projection.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/core/render/view.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/** A solid ellipsoid, in mm relative to the volume's physical centre. `axes[i]` is the unit
 *  direction of semi-axis i in the volume frame; `density` adds mu/mu_water inside. */
struct Ellipsoid {
    Vec3 centre{0, 0, 0};
    Vec3 semiAxes{1, 1, 1};
    std::array<Vec3, 3> axes{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    double density = 1.0;

    /** Length (mm) of the chord of the line o + t dir (dir unit, o relative to the centre). */
    double chord(const Vec3& o, const Vec3& dir) const;
    /** The parameters t0 < t1 where the line enters and leaves; false if it misses. */
    bool interval(const Vec3& o, const Vec3& dir, double& t0, double& t1) const;
    bool contains(const Vec3& p) const;
};

/**
 * Sum of ellipsoids in mu relative to water (air 0). In Hounsfield units a voxel holds
 * HU = 1000 (mu - 1): -1000 wherever no ellipsoid is, inside the volume's box.
 */
class EllipsoidPhantom {
public:
    std::vector<Ellipsoid> ellipsoids;

    /** 3D Shepp-Logan (Kak & Slaney intensities: skull 2.0 = +1000 HU, brain 1.02 = +20 HU,
     *  ventricles 1.0 = 0 HU, lesions 1.03 = +30 HU) scaled so the unit of the classic
     *  normalised coordinates is fieldMm / 2 mm. Geometry after the 3D table of Schabel's
     *  phantom3d with our own tilt convention (rotation about z by phi, then about x by psi). */
    static EllipsoidPhantom sheppLogan3D(double fieldMm);

    /** Voxelises into HU: voxel centres at (i - (N-1)/2) s, each voxel the average over
     *  supersample^3 sub-points where an ellipsoid boundary crosses it (exact elsewhere). */
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

} // namespace fvr::core
