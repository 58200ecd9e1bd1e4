// Running `plastimatch drr` for a Volume and a ConeCamera (plastimatch.h says which of its
// conventions this relies on and how each was found).
#include "support/plastimatch.h"

#include <fvr/core/text.h>

#include <sys/wait.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace fvr::test {
namespace {

/** Text that reads back as the same double (core::formatNumber: the shortest such). */
std::string num(double v) { return core::formatNumber(v); }

std::string triple(const glm::dvec3& v) {
    std::string s = "'";
    s += num(v.x);
    s += ' ';
    s += num(v.y);
    s += ' ';
    s += num(v.z);
    s += '\'';
    return s;
}

/** Single quotes for the shell (paths with spaces or quotes). */
std::string quoted(const std::string& s) {
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

/** The last `maxChars` characters of a text file (plastimatch's log). */
std::string tail(const std::filesystem::path& path, std::size_t maxChars = 1500) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string s = ss.str();
    return s.size() > maxChars ? s.substr(s.size() - maxChars) : s;
}

/** A vector of patient LPS in the volume's index-axis frame (the direction cosines' rows). */
glm::dvec3 rotateToFrame(const core::Volume& volume, const glm::dvec3& x) {
    return {glm::dot(volume.direction[0], x), glm::dot(volume.direction[1], x),
            glm::dot(volume.direction[2], x)};
}

void checkOrthonormal(const core::Volume& volume) {
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            const double d = glm::dot(volume.direction[a], volume.direction[b]);
            if (std::abs(d - (a == b ? 1.0 : 0.0)) > 1e-6)
                throw std::runtime_error("plastimatch: the volume's direction cosines are not "
                                         "orthonormal (axes " +
                                         std::to_string(a) + " and " + std::to_string(b) +
                                         "): plastimatch has no sheared grids");
        }
}

} // namespace

std::string plastimatchMissing() {
    const int st = std::system("plastimatch --version > /dev/null 2>&1");
    if (st != -1 && WIFEXITED(st) && WEXITSTATUS(st) == 0) return {};
    return "plastimatch not found or not runnable (`plastimatch --version` failed): it is a "
           "test-only Debian package, installed by packaging/install-deps.sh --tests (make test)";
}

glm::dvec3 toPlastimatchFrame(const core::Volume& volume, const glm::dvec3& lps) {
    // Voxel index i lies at O + R diag(s) i in LPS and at O + diag(s) i in plastimatch's frame.
    const glm::dvec3 o = volume.origin;
    return o + rotateToFrame(volume, lps - o);
}

std::string PlastimatchGeometry::arguments(const std::string& algorithm) const {
    return "-A cpu -i " + algorithm + " -P none -t pfm --nrm " + triple(nrm) + " --vup " +
           triple(vup) + " --sad " + num(sad) + " --sid " + num(sid) + " -o " + triple(isocenter) +
           " -r '" + std::to_string(width) + " " + std::to_string(height) + "' -z '" +
           num(width * pitchU) + " " + num(height * pitchV) + "' -c '" + num(imageCenter.x) + " " +
           num(imageCenter.y) + "'";
}

PlastimatchGeometry plastimatchGeometry(const core::Volume& volume,
                                        const core::ConeCamera& camera) {
    checkOrthonormal(volume);
    const glm::dvec3 s = toPlastimatchFrame(volume, camera.source);
    const glm::dvec3 c = toPlastimatchFrame(volume, camera.detectorCentre);
    const glm::dvec3 u = rotateToFrame(volume, camera.u);
    const glm::dvec3 v = rotateToFrame(volume, camera.v);
    glm::dvec3 n = glm::normalize(glm::cross(u, v)); // toward the detector
    if (glm::dot(n, c - s) < 0.0) n = -n;
    PlastimatchGeometry g;
    g.sid = glm::dot(n, c - s);
    const glm::dvec3 foot = s + g.sid * n; // where the principal ray meets the detector
    // Our pixel (i, j) lies at foot + (a + (i - cx) pu) u + (b + (j - cy) pv) v.
    const double a = glm::dot(u, c - foot), b = glm::dot(v, c - foot);
    const double cx = 0.5 * (camera.width - 1) - camera.principalOffset.x;
    const double cy = 0.5 * (camera.height - 1) - camera.principalOffset.y;
    g.nrm = -n;
    g.vup = -v; // plastimatch's rows run along -vup: ours along v
    // Its pixel (c, r) lies at foot + (c - icc) pu prt + (r - icr) pv (-vup), prt = nrm x (-vup).
    const glm::dvec3 prt = glm::cross(g.nrm, v);
    g.mirrorColumns = glm::dot(prt, u) < 0.0;
    g.imageCenter = {g.mirrorColumns ? camera.width - 1 - cx + a / camera.pitchU
                                     : cx - a / camera.pitchU,
                     cy - b / camera.pitchV};
    g.width = camera.width;
    g.height = camera.height;
    g.pitchU = camera.pitchU;
    g.pitchV = camera.pitchV;
    // The isocentre only fixes where along the principal ray the source is (cam = iso + sad nrm):
    // take the depth of the volume's centre (any positive depth gives the same rays).
    glm::dvec3 centre = volume.origin;
    for (int k = 0; k < 3; ++k) centre[k] += 0.5 * double(volume.dims[k] - 1) * volume.spacing[k];
    g.sad = glm::dot(centre - s, n);
    if (!(g.sad > 1.0)) g.sad = 0.5 * g.sid;
    g.isocenter = s + g.sad * n;
    return g;
}

void writePlastimatchVolume(const core::Volume& volume, const std::filesystem::path& path) {
    const std::int64_t nx = volume.dims[0], ny = volume.dims[1], nz = volume.dims[2];
    if (volume.voxels.size() != std::size_t(nx * ny * nz))
        throw std::runtime_error("plastimatch: the volume holds " +
                                 std::to_string(volume.voxels.size()) + " voxels, not " +
                                 std::to_string(nx * ny * nz));
    std::ofstream out(path, std::ios::binary);
    if (!out) throw std::runtime_error("plastimatch: cannot write " + path.string());
    // One layer of zeros on every face: origin one voxel back along each index axis.
    out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        << "CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\n"
        << "Offset = " << num(volume.origin[0] - volume.spacing[0]) << " "
        << num(volume.origin[1] - volume.spacing[1]) << " "
        << num(volume.origin[2] - volume.spacing[2]) << "\nCenterOfRotation = 0 0 0\n"
        << "AnatomicalOrientation = RAI\nElementSpacing = " << num(volume.spacing[0]) << " "
        << num(volume.spacing[1]) << " " << num(volume.spacing[2]) << "\nDimSize = " << nx + 2
        << " " << ny + 2 << " " << nz + 2 << "\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n";
    static_assert(std::endian::native == std::endian::little, "MET_FLOAT written little endian");
    const std::vector<float> zeroPlane(std::size_t((nx + 2) * (ny + 2)), 0.0f);
    const std::vector<float> zeroRow(std::size_t(nx + 2), 0.0f);
    const float zero = 0.0f;
    auto write = [&](const float* p, std::size_t n) {
        out.write(reinterpret_cast<const char*>(p), std::streamsize(n * sizeof(float)));
    };
    write(zeroPlane.data(), zeroPlane.size());
    for (std::int64_t z = 0; z < nz; ++z) {
        write(zeroRow.data(), zeroRow.size());
        for (std::int64_t y = 0; y < ny; ++y) {
            write(&zero, 1);
            write(volume.voxels.data() + volume.index(0, y, z), std::size_t(nx));
            write(&zero, 1);
        }
        write(zeroRow.data(), zeroRow.size());
    }
    write(zeroPlane.data(), zeroPlane.size());
    if (!out.flush()) throw std::runtime_error("plastimatch: writing " + path.string() + " failed");
}

std::vector<float> readPlastimatchPfm(const std::filesystem::path& path, int& width, int& height) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("plastimatch: no output image " + path.string());
    std::string magic;
    double scale = 0.0;
    in >> magic >> width >> height >> scale;
    if (!in || magic != "Pf" || width < 1 || height < 1 || !(scale < 0.0))
        throw std::runtime_error("plastimatch: " + path.string() +
                                 ": expected a little-endian grey PFM (Pf, W H, negative scale)");
    in.get(); // the one whitespace character before the data
    std::vector<float> pixels(std::size_t(width) * std::size_t(height));
    in.read(reinterpret_cast<char*>(pixels.data()), std::streamsize(pixels.size() * 4));
    if (in.gcount() != std::streamsize(pixels.size() * 4))
        throw std::runtime_error("plastimatch: " + path.string() + ": truncated (" +
                                 std::to_string(in.gcount()) + " of " +
                                 std::to_string(pixels.size() * 4) + " data bytes)");
    return pixels;
}

glm::dvec2 PlastimatchDrr::project(const core::Volume& volume, const glm::dvec3& lps) const {
    const glm::dvec3 q = toPlastimatchFrame(volume, lps);
    double h[3];
    for (int r = 0; r < 3; ++r)
        h[r] = matrix[4 * r] * q.x + matrix[4 * r + 1] * q.y + matrix[4 * r + 2] * q.z +
               matrix[4 * r + 3];
    const double col = h[0] / h[2] + ic[0];
    return {mirrorColumns ? width - 1 - col : col, h[1] / h[2] + ic[1]};
}

PlastimatchDrr runPlastimatchDrr(const core::Volume& volume, const core::ConeCamera& camera,
                                 const std::filesystem::path& workDir, const std::string& algorithm,
                                 bool reuseVolume) {
    const PlastimatchGeometry g = plastimatchGeometry(volume, camera);
    std::filesystem::create_directories(workDir);
    const std::filesystem::path mha = workDir / "volume.mha";
    if (!reuseVolume || !std::filesystem::exists(mha)) writePlastimatchVolume(volume, mha);
    const std::filesystem::path prefix = workDir / "drr_", log = workDir / "plastimatch.log";
    std::filesystem::remove(workDir / "drr_0000.pfm");
    PlastimatchDrr r;
    r.command = "plastimatch drr " + g.arguments(algorithm) + " -O " + quoted(prefix.string()) +
                " " + quoted(mha.string());
    const auto t0 = std::chrono::steady_clock::now();
    const int st = std::system((r.command + " > " + quoted(log.string()) + " 2>&1").c_str());
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (st == -1 || !WIFEXITED(st) || WEXITSTATUS(st) != 0)
        throw std::runtime_error("plastimatch drr failed (" + r.command + "):\n" + tail(log));
    int w = 0, h = 0;
    std::vector<float> raw = readPlastimatchPfm(workDir / "drr_0000.pfm", w, h);
    if (w != camera.width || h != camera.height)
        throw std::runtime_error("plastimatch: made a " + std::to_string(w) + " x " +
                                 std::to_string(h) + " image for a " +
                                 std::to_string(camera.width) + " x " +
                                 std::to_string(camera.height) + " detector");
    r.width = w;
    r.height = h;
    r.mirrorColumns = g.mirrorColumns;
    r.pixels.resize(raw.size());
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            const int src = g.mirrorColumns ? w - 1 - col : col;
            // plastimatch divides each line integral by 10 (mm to cm); back to value x mm.
            r.pixels[std::size_t(row) * w + col] =
                float(10.0 * double(raw[std::size_t(row) * w + src]));
        }
    std::ifstream mat(workDir / "drr_0000.txt");
    mat >> r.ic[0] >> r.ic[1];
    for (double& m : r.matrix) mat >> m;
    if (!mat)
        throw std::runtime_error("plastimatch: no matrix in " +
                                 (workDir / "drr_0000.txt").string());
    return r;
}

} // namespace fvr::test
