#pragma once
/** Cone-beam cameras as 3x4 projection matrices in a text file, and a camera back from P.
 *
 *  The file (".txt" or any name; UTF-8 or ASCII text, one item a line, '#' starts a comment):
 *
 *      # fvr projection matrix: [w col, w row, w]^T = P [x, y, z, 1]^T, patient LPS mm
 *      detector 1240 960          # W H: columns and rows (16..4096), required, once
 *      pitch 0.194 0.194          # PU [PV]: mm between pixel centres, required, once
 *      P0 P1 P2 P3                # a row of P: four numbers (spaces, tabs or commas)
 *      P4 P5 P6 P7
 *      P8 P9 P10 P11
 *
 *  Three rows make one view; 3N rows, N views (a rotational run), all with the one detector.
 *  Pixel centres are at integer 0-based (col, row), row 0 at the top. P may be scaled by any
 *  positive factor (it is normalised so that its third row's first three numbers have unit
 *  length); its sign must make w > 0 for the points between the source and the detector (-P
 *  is a camera too, its detector mirrored through the source: the volume then lies behind the
 *  source, which the renderers' view check refuses). P
 *  fixes the source, the detector's directions and the principal point, and f / pitch (the
 *  focal length in pixels), but not the detector's distance: the pitch fixes that (SID =
 *  pitch x f in pixels). With one pitch given, PV follows from P (square pixels when P says
 *  so); with both, they must agree with P's aspect ratio. Qt-free. */
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/geometry/camera.h>

namespace fvr::core {

/** The camera whose matrix is P (up to a positive factor) on a W x H detector of column pitch
 *  `pitchU`: source = P's null vector, the detector plane normal = P's third row, u and v from
 *  the first two rows, the detector centre at the foot of the source on the plane (SID = pitchU
 *  x P's focal length in columns), the principal offset from P's principal point. pitchV <= 0:
 *  from P (pitchU x the ratio of P's focal lengths). Throws SettingsError naming the problem:
 *  P singular, skewed (columns not perpendicular to rows), a pitchV that disagrees with P, a bad
 *  detector (ConeCamera::validate). */
ConeCamera cameraFromMatrix(const ProjectionMatrix& p, int width, int height, double pitchU,
                            double pitchV = 0.0);

/** Reads a projection-matrix file: one camera per three rows. Throws LoadError where the file
 *  cannot be read, SettingsError naming path:line for bad content (a row not of four numbers, a
 *  keyword given twice, a missing "detector" or "pitch", rows not a multiple of three, a matrix
 *  cameraFromMatrix refuses). */
std::vector<ConeCamera> readProjectionMatrixFile(const std::filesystem::path& path);

/** The text of a projection-matrix file of these cameras (all with the first one's detector
 *  size and pitch; SettingsError where they differ), numbers at full precision. */
std::string projectionMatrixText(const std::vector<ConeCamera>& cameras);

/** Writes projectionMatrixText to `path` (atomically); WriteError naming it where it fails. */
void writeProjectionMatrixFile(const std::filesystem::path& path,
                               const std::vector<ConeCamera>& cameras);

} // namespace fvr::core
