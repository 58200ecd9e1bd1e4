#pragma once
/** View geometry shared by the CPU renderer, the GPU renderer, the spatial projector and the
 *  analytic phantom projections (docs/dev/algorithm.md, "Geometry"). */
#include <fvr/core/vec3.h>
#include <fvr/core/volume.h>

namespace fvr::core {

/**
 * An orthonormal view frame in the volume's physical frame (axes along the voxel index axes):
 * D = viewing direction, U = up (orthogonalised against D), R = D x U. Pixel (col, row) of an
 * M x M image with pixel size d (mm) is the line integral along D through
 * c + (col - M/2) d R - (row - M/2) d U, with c the volume's physical centre. Row 0 is the top.
 * R is normally D x U; patientViewFrame() sets R = -(D x U) for volumes whose index frame is
 * mirrored against the patient frame, so that images are never shown mirrored.
 */
struct ViewFrame {
    Vec3 d{0, 0, 1};
    Vec3 u{0, -1, 0};
    Vec3 r{1, 0, 0};

    /** Builds the frame; throws SettingsError when dir is zero or up is parallel to dir. */
    static ViewFrame fromDirUp(const Vec3& dir, const Vec3& up);
    /** The frame rotated by `angleRad` about `axis` (right-handed): used for sweeps. */
    ViewFrame rotated(const Vec3& axis, double angleRad) const;
};

/** Projection image geometry: W x H pixels of size d (mm), W = size and H = height (0: square).
 *  The volume's centre projects onto pixel (W/2, H/2) (integer division), as on M x M. The
 *  Fourier renderers transform a square of side fourierSide() (with the volume) and crop it
 *  about that pixel. */
struct ImageGeometry {
    int size = 256; ///< W, the columns (and the rows when height is 0)
    double pixelSize = 1.0;
    int height = 0; ///< H, the rows; 0: as many as the columns

    int cols() const { return size; }
    int rows() const { return height > 0 ? height : size; }
    bool square() const { return rows() == cols(); }
};

/** The side of the square the Fourier renderers transform for a W x H image: the smallest
 *  M >= max(W, H, 16) that is even and has no prime factor above 7 (FFTW's fast sizes), or
 *  the smallest power of two (`powerOfTwo`: the GPU's FFT). */
int fourierSide(int width, int height, bool powerOfTwo);
/** The same for an image of this volume. A square whose side is already such an M renders
 *  as it always has (its period M d is the user's choice: a pixel size below the default makes
 *  the copies overlap, as on the paper's fig. 6). Any other W x H takes M d >= D too, D the
 *  voxel grid's diagonal and d the pixel size (at most 4096): the period of a square image at
 *  the default pixel size, so that a crop has its accuracy, never a smaller square's periodic
 *  copies or folded kernel ghosts. With the default pixel size (D over min(W, H)) that is
 *  fourierSide(W, H) itself. */
int fourierSide(const ImageGeometry& image, const Dims3& dims, const Vec3& spacing,
                bool powerOfTwo);

/** Pixel (col, row) of the centred W x H crop of an M x M image is pixel
 *  (col + (M/2 - W/2), row + (M/2 - H/2)) of it: the crop keeps the centre pixel. */
struct CropOffset {
    int col = 0;
    int row = 0;
};
inline CropOffset centredCrop(int M, int width, int height) {
    return {M / 2 - width / 2, M / 2 - height / 2};
}

/** The default pixel size: the volume's physical diagonal spread over M pixels, so that the
 *  projection of any view fits the image period M*d (no overlapping copies). For W x H, pass
 *  min(W, H): the diagonal then fits both ways. */
double defaultPixelSize(const Dims3& dims, const Vec3& spacing, int size);

/** Half extents (mm, around the volume's centre) of the box outside which the voxel model is 0:
 *  ((N_a - 1) / 2 + reach) s_a, reach in voxels beyond the outermost voxel centres
 *  (voxelModelReach: 1 for trilinear, exactly). */
Vec3 supportHalfExtents(const Dims3& dims, const Vec3& spacing, double reach);

/** Whether the ray of pixel (col, row) of an M x M image with pixel size d misses the box of half
 *  extents `half` around the volume's centre (supportHalfExtents): its true line integral is then
 *  0 (exactly for the trilinear model; voxelModelReach; clipToVolume in RenderParams). */
bool rayMissesVolume(const ViewFrame& view, const Vec3& half, int M, double d, int col, int row);

/** The columns [first, last] of image row `row` whose rays hit the box (rayMissesVolume false
 *  exactly there; the shadow of a box is convex, so they are one run). first > last: none.
 *  Costs a few tests per row instead of one per pixel (the CPU renderer's clip). */
struct ColumnRange {
    int first = 0;
    int last = -1;
};
ColumnRange volumeShadowColumns(const ViewFrame& view, const Vec3& half, int M, double d, int row);

/** Checks that W and H are in [16, 4096] and the pixel size > 0; throws SettingsError. The
 *  renderers' own range: the workstation offers RenderSettings' sizes (render_settings.h), and
 *  the progressive refinement's interactive levels render smaller ones. */
void validateImageGeometry(const ImageGeometry& g);

/** How far the image's span M d may stray from the volume's diagonal (the default pixel size
 *  makes them equal): between 1/kFieldOfViewFactor and kFieldOfViewFactor times it. */
inline constexpr double kFieldOfViewFactor = 64.0;

/** The pixel sizes (mm) an M-pixel image of this volume may have: the span rule above, and
 *  pixels coarse enough that the slice's highest frequency stays within
 *  TransferTable::kMaxCyclesPerVoxel for every view (a pixel at least ~1/2900 of the largest
 *  voxel spacing). */
struct PixelSizeRange {
    double min = 0.0;
    double max = 0.0;
};
PixelSizeRange pixelSizeRange(const Dims3& dims, const Vec3& spacing, int size);

/** validateImageGeometry, then the pixel size against pixelSizeRange: a SettingsError giving
 *  the numbers ("pixel size 1e-06 mm: the 128-pixel image would span 0.000128 mm of a volume
 *  whose diagonal is 55.4 mm; expected ..."). What keeps a tiny pixel size from making the
 *  renderers' tables (and the memory) grow without bound; every front end goes through it
 *  (validateRenderParams with the spectrum, fvr-render's and the Python module's geometry). */
void validateImageGeometry(const ImageGeometry& g, const Dims3& dims, const Vec3& spacing);

} // namespace fvr::core
