#pragma once
/** The reader's measurements without Qt: distances, angles, ROI statistics over a pixel mask, a
 *  round scale-bar length and the 90° turns and mirrors of image points. Points are in image
 *  pixel units (continuous): pixel (col, row) covers [col, col + 1) x [row, row + 1), its centre
 *  at (col + 0.5, row + 0.5); rows go down. */
#include <cstddef>
#include <vector>

namespace fvr::ui::measure {

struct Point {
    double x = 0.0, y = 0.0;
};

/** Length of the segment a-b in mm for a pixel size of `pixelMm` (square pixels). */
double distanceMm(Point a, Point b, double pixelMm);

/** The angle at `vertex` between the rays to a and b, in degrees in [0, 180]; 0 when a ray has
 *  no length. */
double angleDeg(Point a, Point vertex, Point b);

enum class RoiShape { Rectangle, Ellipse };

/** Statistics of the pixels whose centres lie inside the shape spanned by the corners a and b
 *  (the rectangle, or the ellipse inscribed in it; a boundary centre counts as inside). SD is
 *  the population SD (numpy's std, ddof = 0). Area = count x pixel area. */
struct RoiStats {
    std::size_t count = 0;
    double mean = 0.0, sd = 0.0, min = 0.0, max = 0.0;
    double areaMm2 = 0.0;
};

/** Whether the centre of pixel (col, row) lies inside the shape with corners a and b. */
bool insideRoi(RoiShape shape, Point a, Point b, int col, int row);

/** `pixels` is width x height, row-major. Pixels outside the image are ignored. */
RoiStats roiStats(const std::vector<float>& pixels, int width, int height, RoiShape shape, Point a,
                  Point b, double pixelMm);

/** The largest of 1, 2, 5 x 10^k mm not longer than `maxMm` (0 for maxMm <= 0). */
double roundScaleLength(double maxMm);

/** What a displayed image's turn or mirror does to a point of a square image of side `side`:
 *  a quarter turn clockwise on screen, mirrored left-right, mirrored top-bottom. */
enum class Turn { Clockwise, CounterClockwise, FlipHorizontal, FlipVertical };
Point turned(Point p, Turn t, double side);

} // namespace fvr::ui::measure
