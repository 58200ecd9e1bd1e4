#pragma once
/** `plastimatch drr` (Debian's plastimatch 1.9.4) as an independent oracle of the cone-beam
 *  projector: it writes a Volume as plastimatch reads it, turns a ConeCamera into plastimatch's
 *  options, runs it and reads its image back in our pixel order and units. What was found of
 *  plastimatch's conventions, each checked by experiment (tests/unit/test_cone_plastimatch.cpp):
 *   - Geometry: a source at `isocenter + sad * nrm` (nrm points from the isocentre to the source),
 *     the detector plane at `sid` from the source along -nrm, centred on the principal ray; its
 *     rows run along -vup (row 0 at the top, toward vup) and its columns along vup x nrm, so
 *     that columns x rows points away from the source: plastimatch looks at its image from the
 *     source's side. Our C-arm camera looks from behind the detector (u x v toward the source),
 *     so plastimatch's columns are ours mirrored; a mirror in the volume's direction cosines
 *     (det -1) undoes that. Pixel centres at integer indices, the principal point at -c.
 *   - `-r`, `-z` and `-c` read "columns rows", although `--help` says "row col" (a 200 x 100
 *     detector made by -r "200 100" is 200 columns wide; its PFM header says 200 100).
 *   - Output (-t pfm): little-endian float rows written top row first (PFM readers would show
 *     it upside down), plus a text file holding ic (the principal point, columns first) and
 *     the 3x4 matrix P with (col, row) = P x / w + ic.
 *   - Values: `-P none` integrates the raw voxel values; the default (`preprocess`) maps HU to
 *     0.022 (1 + HU/1000) per mm above -800 HU and 0 below. Every line integral is divided by
 *     10 (mm to cm): its images are value x cm; we multiply by 10 (value x mm).
 *   - The volume: origin and spacing honoured, direction cosines ignored (the index axes are
 *     taken as x, y, z); voxel k fills [origin + (k - 1/2) s, origin + (k + 1/2) s] (box
 *     model). The ray is traced over the whole line through the box, not stopped at the
 *     detector. Each ray's last segment, in the voxel where it leaves the box, is left out.
 *  So the volume is written with its index axes as plastimatch's axes (the camera moved into
 *  that frame instead: a rigid motion, exact), padded with one layer of zero voxels on every face
 *  (the dropped exit segment then always lies in a zero voxel), and the columns mirrored back. */
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <fvr/core/geometry/camera.h>
#include <fvr/core/volume.h>

namespace fvr::test {

/** Empty when `plastimatch` runs; otherwise why not (for GTEST_SKIP and the bench). */
std::string plastimatchMissing();

/** plastimatch's options for one camera, in the frame of a volume written by
 *  writePlastimatchVolume (the volume's origin fixed, its index axes along x, y, z). */
struct PlastimatchGeometry {
    glm::dvec3 nrm{0.0}; ///< unit, from the isocentre toward the source
    glm::dvec3 vup{0.0}; ///< unit, toward the top row
    glm::dvec3 isocenter{0.0}; ///< a point on the principal ray (the volume centre's depth)
    double sad = 0.0; ///< source to isocenter
    double sid = 0.0; ///< source to the detector plane
    int width = 0;
    int height = 0;
    double pitchU = 0.0;
    double pitchV = 0.0;
    glm::dvec2 imageCenter{0.0}; ///< plastimatch's -c (columns first), in its own columns
    bool mirrorColumns = false; ///< its column c is our column W - 1 - c
    /** The `plastimatch drr` arguments after "drr", without -O and the input. */
    std::string arguments(const std::string& algorithm = "exact") const;
};

/** The frame change: a point in patient LPS to plastimatch's frame of `volume`. */
glm::dvec3 toPlastimatchFrame(const core::Volume& volume, const glm::dvec3& lps);

/** Throws std::runtime_error when the volume's direction cosines are not orthonormal (a
 *  sheared grid has no rigid frame change). */
PlastimatchGeometry plastimatchGeometry(const core::Volume& volume, const core::ConeCamera& camera);

/** Writes `volume` as a MetaImage (.mha, float32) that plastimatch reads as the same object:
 *  identity direction, one layer of zeros around it (see above). */
void writePlastimatchVolume(const core::Volume& volume, const std::filesystem::path& path);

struct PlastimatchDrr {
    int width = 0;
    int height = 0;
    /** Row * width + col in the camera's own pixel order (row 0 at the top); value x mm. */
    std::vector<float> pixels;
    std::string command;
    double seconds = 0.0; ///< the plastimatch run (not the volume's writing)
    /** plastimatch's own matrix file: the 3x4 P (its frame) and ic. */
    double matrix[12] = {};
    double ic[2] = {0.0, 0.0};
    bool mirrorColumns = false;
    /** Where plastimatch's matrix puts a point of patient LPS, in our (col, row). */
    glm::dvec2 project(const core::Volume& volume, const glm::dvec3& lps) const;
};

/** Writes the volume into `workDir` (an existing .mha there is reused when `reuseVolume`),
 *  runs `plastimatch drr -i <algorithm> -P none` for the camera and reads the image back.
 *  Throws std::runtime_error naming the step, with the end of plastimatch's output. */
PlastimatchDrr runPlastimatchDrr(const core::Volume& volume, const core::ConeCamera& camera,
                                 const std::filesystem::path& workDir,
                                 const std::string& algorithm = "exact", bool reuseVolume = false);

/** Reads plastimatch's PFM (header "Pf", "W H", a negative scale for little endian; rows top
 *  first as plastimatch writes them). Throws std::runtime_error naming the file. */
std::vector<float> readPlastimatchPfm(const std::filesystem::path& path, int& width, int& height);

} // namespace fvr::test
