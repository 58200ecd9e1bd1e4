// The built-in chest phantom: an adult thorax from painted ellipsoids (see phantom.h for the
// anatomy and the sources of the densities). Frame LPS, mm from the volume's centre, built for a
// 420 mm field and scaled to the one asked for.
#include <fvr/core/xray/phantom.h>

#include <cmath>
#include <numbers>

namespace fvr::core {
namespace {

// Densities, mu / mu_water near 70 keV (phantom.h says where they come from).
constexpr double kAir = 0.0;
constexpr double kLung = 0.25;
constexpr double kFat = 0.92;
constexpr double kSoft = 1.04;
constexpr double kBlood = 1.06;
constexpr double kCancellous = 1.20;
constexpr double kProcess = 1.50; // vertebral arches and processes: thin cortex round marrow
constexpr double kRib = 1.60; // a rib's section: mostly cortex
constexpr double kCortical = 1.85;

/** An axis-aligned ellipsoid. */
Ellipsoid box(const Vec3& centre, const Vec3& semi, double density) {
    Ellipsoid e;
    e.centre = centre;
    e.semiAxes = semi;
    e.density = density;
    return e;
}

/** An ellipsoid from p0 to p1 (semi-axis `stretch` x half their distance along the line), `thick`
 *  across it horizontally and `tall` across it in the plane holding the line and +z. */
Ellipsoid along(const Vec3& p0, const Vec3& p1, double thick, double tall, double density,
                double stretch = 1.0) {
    const Vec3 d = p1 - p0;
    const Vec3 a0 = glm::normalize(d);
    Vec3 up{0, 0, 1};
    if (std::abs(a0[2]) > 0.95) up = {0, -1, 0};
    const Vec3 a2 = glm::normalize(up - a0 * glm::dot(up, a0));
    Ellipsoid e;
    e.centre = (p0 + p1) * 0.5;
    e.semiAxes = {stretch * 0.5 * std::sqrt(glm::dot(d, d)), thick, tall};
    e.axes = {a0, glm::cross(a2, a0), a2};
    e.density = density;
    return e;
}

/** A tube through the points, one ellipsoid per piece, overlapping at the joints. */
void tube(std::vector<Ellipsoid>& out, const std::vector<Vec3>& points, double r0, double r1,
          double density) {
    const std::size_t n = points.size() - 1;
    for (std::size_t i = 0; i < n; ++i) {
        const double r = r0 + (r1 - r0) * double(i) / double(std::max<std::size_t>(1, n - 1));
        out.push_back(along(points[i], points[i + 1], r, r, density, 1.25));
    }
}

/** Mirror to the patient's other side (x -> -x). */
Vec3 mirror(const Vec3& p) { return {-p[0], p[1], p[2]}; }

void addBody(std::vector<Ellipsoid>& out) {
    // Fat under the skin, then muscle and organs inside: torso, shoulder girdle and neck.
    const Ellipsoid torso = box({0, 0, -120}, {172, 112, 340}, kFat);
    const Ellipsoid girdle = box({0, 8, 108}, {196, 88, 72}, kFat);
    const Ellipsoid neck = box({0, 14, 240}, {58, 58, 100}, kFat);
    for (const Ellipsoid& e : {torso, girdle, neck}) out.push_back(e);
    for (Ellipsoid e : {torso, girdle, neck}) {
        e.semiAxes = e.semiAxes - 12.0;
        e.density = kSoft;
        out.push_back(e);
    }
}

void addLungs(std::vector<Ellipsoid>& out) {
    for (double s : {-1.0, 1.0}) {
        out.push_back(box({s * 74, 6, 38}, {54, 70, 116}, kLung)); // upper lobe, apex +154
        out.push_back(box({s * 78, 2, -44}, {65, 80, 86}, kLung)); // lower lobe, wide base
        out.push_back(box({s * 116, 10, -100}, {28, 60, 36}, kLung)); // costophrenic recess
    }
}

/** Pulmonary arteries from the hila, branching into the lungs (the lung markings). */
void addLungVessels(std::vector<Ellipsoid>& out) {
    const std::vector<Vec3> ends = {{78, 0, 120},  {108, 4, 62},  {116, 8, 10}, {104, 14, -50},
                                    {62, 20, -74}, {88, -44, -6}, {84, 52, 6}};
    for (double s : {-1.0, 1.0}) {
        const Vec3 root{s * 12, 2, 34}, hilum{s * 50, 6, 24};
        out.push_back(along(root, hilum, 10, 10, kBlood, 1.1));
        for (const Vec3& e : ends) {
            const Vec3 end = s < 0 ? mirror(e) : e;
            const Vec3 mid = hilum + (end - hilum) * 0.5;
            tube(out, {hilum, mid, end}, 6.0, 3.5, kBlood);
            // Two twigs from the end of each branch.
            const Vec3 dir = end - hilum;
            const Vec3 side = glm::normalize(glm::cross(dir, Vec3{0, 0.3, 1}));
            for (double t : {-1.0, 1.0})
                out.push_back(
                    along(end, end + (dir * 0.28 + side * (t * 16)), 2.0, 2.0, kBlood, 1.1));
        }
    }
}

void addHeartAndVessels(std::vector<Ellipsoid>& out) {
    // Heart: long axis from the base (right, up, back) to the apex (left, down, front).
    Ellipsoid heart;
    heart.centre = {26, -20, -38};
    const Vec3 a0 = glm::normalize(Vec3{1.0, -0.4, -0.6});
    const Vec3 a1 = glm::normalize(glm::cross(Vec3{0, 0, 1}, a0));
    heart.axes = {a0, a1, glm::cross(a0, a1)};
    heart.semiAxes = {74, 52, 50};
    heart.density = kBlood;
    out.push_back(heart);
    // Aorta: ascending (right of the midline), arch, knob left of the trachea, descending.
    tube(out, {{-14, -28, -10}, {-16, -24, 40}, {-10, -18, 74}, {6, 0, 86}, {24, 18, 76}}, 15.0,
         14.0, kBlood);
    tube(out, {{24, 18, 76}, {26, 36, 52}, {22, 44, 0}, {18, 46, -80}, {10, 44, -220}}, 13.5, 12.5,
         kBlood);
    out.push_back(along({-30, -16, 20}, {-28, -12, 130}, 11, 11, kBlood)); // superior vena cava
    out.push_back(along({0, -30, 10}, {12, -16, 50}, 14, 14, kBlood)); // pulmonary trunk
}

void addAbdomenAndAirways(std::vector<Ellipsoid>& out) {
    out.push_back(box({-62, 2, -176}, {122, 96, 100}, kBlood)); // right dome: liver below
    out.push_back(box({70, 2, -196}, {112, 96, 100}, kSoft)); // left dome: spleen, stomach
    out.push_back(box({70, -12, -112}, {36, 28, 16}, kAir)); // stomach gas bubble
    out.push_back(along({0, -6, 230}, {0, 6, 52}, 9, 9, kAir)); // trachea, carina at T5
    out.push_back(along({0, 6, 56}, {-34, 8, 30}, 7, 7, kAir, 1.1)); // right main bronchus
    out.push_back(along({0, 6, 56}, {44, 10, 22}, 6, 6, kAir, 1.1)); // left main bronchus
}

/** Vertebra centre heights: C6 .. L2 with T1 at +148 mm, 27 mm apart. */
double vertebraZ(int level) { return 148.0 - 27.0 * (level - 1); } // level 1 = T1

void addSpine(std::vector<Ellipsoid>& out) {
    for (int level = -1; level <= 15; ++level) { // C6, C7, T1..T12, L1..L3
        const double z = vertebraZ(level);
        const double g = level < 1 ? 0.75 : level > 12 ? 1.15 : 1.0 + 0.01 * level;
        const Vec3 body{0, 46, z};
        out.push_back(box(body, {20 * g, 15 * g, 10.5}, kCortical));
        out.push_back(box(body, {20 * g - 1.0, 15 * g - 1.0, 9.5}, kCancellous));
        out.push_back(box({0, 70, z}, {18 * g, 6, 8}, kProcess)); // arch with the pedicles
        out.push_back(along({0, 74, z}, {0, 96, z - 16}, 4, 7, kProcess)); // spinous process
        for (double s : {-1.0, 1.0})
            out.push_back(along({s * 10, 66, z + 2}, {s * 40, 70, z + 4}, 6, 6, kProcess));
    }
}

/** One rib: from the tip of its vertebra's transverse process round the lung on an elliptic
 *  arc (half width w, half depth d about y = yc), falling `drop` mm towards its front end. */
void addRib(std::vector<Ellipsoid>& out, int rib, double w, double d, double yc, double end,
            double drop) {
    const double z0 = vertebraZ(rib) + 4.0;
    const int pieces = 10;
    const double th0 = std::asin(std::min(1.0, 44.0 / w));
    for (double s : {-1.0, 1.0}) {
        std::vector<Vec3> pts{{s * 34, 70, z0}};
        for (int k = 0; k <= pieces; ++k) {
            const double u = double(k) / pieces, th = th0 + (end - th0) * u;
            const double z = z0 + 8.0 * std::sin(std::numbers::pi * std::min(1.0, 2 * u)) -
                             drop * std::pow(u, 1.5);
            pts.push_back({s * w * std::sin(th), yc + d * std::cos(th), z});
        }
        for (std::size_t k = 0; k + 1 < pts.size(); ++k)
            out.push_back(
                along(pts[k], pts[k + 1], rib == 1 ? 4.5 : 3.5, rib == 1 ? 5.0 : 6.5, kRib, 1.3));
    }
}

void addRibs(std::vector<Ellipsoid>& out) {
    constexpr double pi = std::numbers::pi;
    // Half width, half depth, centre depth, front end (angle from the back), drop (mm).
    const double table[12][5] = {
        {72, 48, 18, 0.86 * pi, 36}, {104, 62, 10, 0.84 * pi, 62}, {122, 74, 4, 0.82 * pi, 78},
        {132, 82, 0, 0.80 * pi, 88}, {139, 88, 0, 0.80 * pi, 94},  {143, 90, 0, 0.79 * pi, 96},
        {146, 90, 0, 0.77 * pi, 96}, {147, 90, 0, 0.74 * pi, 92},  {146, 90, 0, 0.70 * pi, 86},
        {142, 88, 0, 0.64 * pi, 74}, {136, 86, 2, 0.52 * pi, 50},  {122, 84, 4, 0.40 * pi, 34}};
    for (int r = 1; r <= 12; ++r) {
        const auto& t = table[r - 1];
        addRib(out, r, t[0], t[1], t[2], t[3], t[4]);
    }
}

void addShoulderGirdle(std::vector<Ellipsoid>& out) {
    // Sternum: manubrium, body, xiphoid (the body's lower end leans forward).
    out.push_back(box({0, -90, 122}, {26, 6, 24}, 1.35));
    out.push_back(along({0, -92, 98}, {0, -100, -12}, 15, 6, 1.35));
    out.push_back(along({0, -100, -14}, {0, -102, -38}, 8, 4, 1.2));
    for (double s : {-1.0, 1.0}) {
        // Clavicle: from the manubrium out, back and up to the acromion.
        tube(out,
             {{s * 22, -84, 136}, {s * 70, -88, 142}, {s * 118, -66, 150}, {s * 152, -24, 160}},
             7.0, 6.0, kCortical);
        // Scapula: a plate on the posterolateral chest wall, its lateral border and the glenoid.
        Ellipsoid sc = box({s * 108, 84, 84}, {46, 5, 72}, 1.4);
        const double a = s * 0.62;
        sc.axes = {Vec3{std::cos(a), std::sin(a), 0}, Vec3{-std::sin(a), std::cos(a), 0},
                   Vec3{0, 0, 1}};
        out.push_back(sc);
        out.push_back(along({s * 146, 40, 124}, {s * 118, 80, 20}, 6, 6, 1.5));
        // Humeral head: cancellous bone in a cortical shell.
        out.push_back(box({s * 158, 10, 126}, {23, 23, 23}, 1.8));
        out.push_back(box({s * 158, 10, 126}, {20.5, 20.5, 20.5}, 1.3));
    }
}

} // namespace

EllipsoidPhantom EllipsoidPhantom::chest(double fieldMm) {
    EllipsoidPhantom p;
    p.composition = Composition::Paint;
    auto& e = p.ellipsoids;
    addBody(e);
    addLungs(e);
    addLungVessels(e);
    addHeartAndVessels(e);
    addAbdomenAndAirways(e);
    addSpine(e);
    addRibs(e);
    addShoulderGirdle(e);
    const double f = fieldMm / 420.0;
    for (Ellipsoid& x : e) {
        x.centre = x.centre * f;
        x.semiAxes = x.semiAxes * f;
    }
    return p;
}

} // namespace fvr::core
