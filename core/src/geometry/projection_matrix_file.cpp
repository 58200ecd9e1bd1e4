// Cone-beam cameras as 3x4 projection matrices: the camera back from P, and the text file
// (projection_matrix_file.h).
#include <fvr/core/geometry/projection_matrix_file.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/text.h>

namespace fvr::core {
namespace {

/** A short number for messages (6 significant digits). */
std::string shortNumber(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

} // namespace

ConeCamera cameraFromMatrix(const ProjectionMatrix& p, int width, int height, double pitchU,
                            double pitchV) {
    const auto fail = [](const std::string& what) {
        throw SettingsError("projection matrix: " + what);
    };
    for (const auto& r : p.rows)
        if (!std::isfinite(r.x) || !std::isfinite(r.y) || !std::isfinite(r.z) ||
            !std::isfinite(r.w))
            fail("a number is not finite");
    if (!(pitchU > 0.0) || !std::isfinite(pitchU))
        fail("column pitch: expected a positive number of mm, found " + shortNumber(pitchU));
    // Normalise: the third row's direction is the detector's unit normal (w = depth in mm).
    const double scale = glm::length(glm::dvec3(p.rows[2]));
    if (!(scale > 0.0)) fail("the third row's first three numbers are 0 (no depth)");
    glm::dvec4 rows[3];
    for (int i = 0; i < 3; ++i) rows[i] = p.rows[i] / scale;
    // glm is column-major: the rows of M are its transpose's columns.
    const glm::dmat3 m =
        glm::transpose(glm::dmat3(glm::dvec3(rows[0]), glm::dvec3(rows[1]), glm::dvec3(rows[2])));
    const glm::dvec3 a(rows[0]), b(rows[1]), n(rows[2]);
    const double det = glm::determinant(m);
    if (!(std::abs(det) > 1e-12 * glm::length(a) * glm::length(b)))
        fail("its left 3x3 block is singular (no finite source)");
    ConeCamera c;
    c.source = -(glm::inverse(m) * glm::dvec3(rows[0].w, rows[1].w, rows[2].w));
    // a = (f / pu) u + cx n, b = (f / pv) v + cy n with the detector centre at the source's
    // foot on the plane (camera.cpp's matrix()).
    const glm::dvec3 aPerp = a - glm::dot(a, n) * n, bPerp = b - glm::dot(b, n) * n;
    const double fu = glm::length(aPerp), fv = glm::length(bPerp); // focal lengths, pixels
    c.u = aPerp / fu;
    c.v = bPerp / fv;
    if (std::abs(glm::dot(c.u, c.v)) > 1e-9)
        fail("it is skewed: the detector's columns and rows are not perpendicular (u.v = " +
             shortNumber(glm::dot(c.u, c.v)) + ")");
    const double f = pitchU * fu;
    if (pitchV <= 0.0) {
        pitchV = f / fv;
    } else if (std::abs(pitchV * fv - f) > 1e-9 * f) {
        fail("row pitch " + shortNumber(pitchV) + " mm disagrees with P, which gives " +
             shortNumber(f / fv) + " mm for a column pitch of " + shortNumber(pitchU) + " mm");
    }
    c.detectorCentre = c.source + f * n;
    c.width = width;
    c.height = height;
    c.pitchU = pitchU;
    c.pitchV = pitchV;
    c.principalOffset = {0.5 * (width - 1) - glm::dot(a, n), 0.5 * (height - 1) - glm::dot(b, n)};
    c.validate();
    return c;
}

namespace {

/** The numbers of a line (commas as spaces) after an optional keyword; nothing for a token
 *  that is not a finite number. */
struct Line {
    std::string keyword; ///< lower case; empty for a row of numbers
    std::vector<double> numbers;
    std::optional<std::string> bad; ///< the first token that is not a number
};

Line splitLine(std::string text) {
    if (const auto hash = text.find('#'); hash != std::string::npos) text.erase(hash);
    for (char& ch : text)
        if (ch == ',' || ch == '\t' || ch == '\r') ch = ' ';
    std::istringstream in(text);
    Line line;
    std::string token;
    bool first = true;
    while (in >> token) {
        const auto v = parseNumber<double>(token);
        if (first && !v) {
            line.keyword = asciiLower(token);
        } else if (!v || !std::isfinite(*v)) {
            if (!line.bad) line.bad = token;
        } else {
            line.numbers.push_back(*v);
        }
        first = false;
    }
    return line;
}

struct FileContent {
    std::optional<std::pair<int, int>> detector;
    std::optional<std::pair<double, double>> pitch; ///< PV 0: from P
    std::vector<std::pair<int, glm::dvec4>> rows; ///< line number, row
};

FileContent parseContent(std::istream& in, const std::string& path) {
    FileContent content;
    std::string text;
    int lineNo = 0;
    int detectorLine = 0, pitchLine = 0;
    while (std::getline(in, text)) {
        ++lineNo;
        const std::string at = path + ":" + std::to_string(lineNo) + ": ";
        const Line line = splitLine(text);
        if (line.bad) throw SettingsError(at + "expected a number, found '" + *line.bad + "'");
        const auto& v = line.numbers;
        if (line.keyword == "detector") {
            if (detectorLine)
                throw SettingsError(at + "a second 'detector' line (the first on line " +
                                    std::to_string(detectorLine) + ")");
            if (v.size() != 2 || v[0] != std::floor(v[0]) || v[1] != std::floor(v[1]))
                throw SettingsError(at + "expected 'detector W H' (two whole numbers of pixels)");
            content.detector = {int(v[0]), int(v[1])};
            detectorLine = lineNo;
        } else if (line.keyword == "pitch") {
            if (pitchLine)
                throw SettingsError(at + "a second 'pitch' line (the first on line " +
                                    std::to_string(pitchLine) + ")");
            if (v.empty() || v.size() > 2)
                throw SettingsError(at + "expected 'pitch PU [PV]' (mm)");
            content.pitch = {v[0], v.size() == 2 ? v[1] : 0.0};
            if (!(v[0] > 0.0) || (v.size() == 2 && !(v[1] > 0.0)))
                throw SettingsError(at + "expected a positive pitch in mm");
            pitchLine = lineNo;
        } else if (!line.keyword.empty()) {
            throw SettingsError(at + "unknown keyword '" + line.keyword +
                                "' (expected 'detector', 'pitch' or a row of four numbers)");
        } else if (!v.empty()) {
            if (v.size() != 4)
                throw SettingsError(at + "expected a row of P: four numbers, found " +
                                    std::to_string(v.size()));
            content.rows.emplace_back(lineNo, glm::dvec4(v[0], v[1], v[2], v[3]));
        }
    }
    return content;
}

} // namespace

std::vector<ConeCamera> readProjectionMatrixFile(const std::filesystem::path& path) {
    std::ifstream in(path);
    const std::string name = path.string();
    if (!in) throw LoadError(name + ": cannot open the projection-matrix file");
    const FileContent content = parseContent(in, name);
    if (in.bad()) throw LoadError(name + ": cannot read the projection-matrix file");
    if (!content.detector) throw SettingsError(name + ": no 'detector W H' line");
    if (!content.pitch) throw SettingsError(name + ": no 'pitch PU [PV]' line");
    if (content.rows.empty())
        throw SettingsError(name + ": no matrix (three rows of four numbers)");
    if (content.rows.size() % 3 != 0)
        throw SettingsError(
            name + ":" + std::to_string(content.rows.back().first) + ": " +
            std::to_string(content.rows.size()) +
            " rows of P in the file, not a multiple of three (each view has three)");
    std::vector<ConeCamera> cameras;
    for (std::size_t i = 0; i < content.rows.size(); i += 3) {
        ProjectionMatrix p;
        for (int r = 0; r < 3; ++r) p.rows[r] = content.rows[i + r].second;
        try {
            cameras.push_back(cameraFromMatrix(p, content.detector->first, content.detector->second,
                                               content.pitch->first, content.pitch->second));
        } catch (const SettingsError& e) {
            throw SettingsError(name + ":" + std::to_string(content.rows[i].first) + ": " +
                                e.what());
        }
    }
    return cameras;
}

std::string projectionMatrixText(const std::vector<ConeCamera>& cameras) {
    if (cameras.empty()) throw SettingsError("projection matrix file: no camera to write");
    const ConeCamera& first = cameras.front();
    std::string text =
        "# fvr projection matrix: [w col, w row, w]^T = P [x, y, z, 1]^T, patient LPS "
        "mm,\n# pixel centres at integer 0-based (col, row), row 0 at the top; "
        "w > 0 in front of the source\n";
    text += "detector " + std::to_string(first.width) + " " + std::to_string(first.height) + "\n";
    text += "pitch " + formatNumber(first.pitchU) + " " + formatNumber(first.pitchV) + "\n";
    for (std::size_t i = 0; i < cameras.size(); ++i) {
        const ConeCamera& c = cameras[i];
        if (c.width != first.width || c.height != first.height || c.pitchU != first.pitchU ||
            c.pitchV != first.pitchV)
            throw SettingsError("projection matrix file: view " + std::to_string(i) +
                                " has another detector size or pitch than view 0");
        const ProjectionMatrix p = c.matrix();
        text += "# view " + std::to_string(i) + "\n";
        for (const auto& r : p.rows)
            text += formatNumber(r.x) + " " + formatNumber(r.y) + " " + formatNumber(r.z) + " " +
                    formatNumber(r.w) + "\n";
    }
    return text;
}

void writeProjectionMatrixFile(const std::filesystem::path& path,
                               const std::vector<ConeCamera>& cameras) {
    writeFileAtomic(path, projectionMatrixText(cameras));
}

} // namespace fvr::core
