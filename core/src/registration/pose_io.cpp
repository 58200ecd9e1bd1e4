// Pose files and target points (registration/registration_io.h).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include <fvr/core/errors.h>
#include <fvr/core/io/atomic_file.h>
#include <fvr/core/registration/registration_io.h>

namespace fvr::core {

namespace {

using Json = nlohmann::json;

[[noreturn]] void poseFileError(const std::filesystem::path& path, const std::string& what) {
    throw LoadError("pose file " + path.string() + ": " + what);
}

glm::dvec3 vec3Of(const Json& j, const char* key, const std::filesystem::path& path) {
    const Json& v = j.at(key);
    if (!v.is_array() || v.size() != 3)
        poseFileError(path, std::string("\"") + key + "\" must be an array of 3 numbers");
    glm::dvec3 out;
    for (int k = 0; k < 3; ++k) {
        if (!v[k].is_number())
            poseFileError(path, std::string("\"") + key + "\" holds a non-number");
        out[k] = v[k].get<double>();
    }
    return out;
}

glm::dmat4 matrixOf(const Json& m, const std::filesystem::path& path) {
    if (!m.is_array() || m.size() != 4)
        poseFileError(path, "\"matrix\" must be 4 rows of 4 numbers (row-major), it has " +
                                std::to_string(m.is_array() ? m.size() : 0) + " rows");
    glm::dmat4 t(1.0);
    for (int r = 0; r < 4; ++r) {
        if (!m[r].is_array() || m[r].size() != 4)
            poseFileError(path, "\"matrix\" row " + std::to_string(r + 1) + " must hold 4 numbers");
        for (int c = 0; c < 4; ++c) {
            if (!m[r][c].is_number())
                poseFileError(path,
                              "\"matrix\" row " + std::to_string(r + 1) + " holds a non-number");
            t[c][r] = m[r][c].get<double>();
        }
    }
    return t;
}

/** The pose object of a file: the file itself, or a registration result's "pose". */
const Json& poseObject(const Json& j, const std::filesystem::path& path) {
    if (!j.is_object()) poseFileError(path, "not a JSON object");
    if (j.contains("pose") && j["pose"].is_object()) return j["pose"];
    return j;
}

} // namespace

glm::dmat4 readPoseJson(const std::filesystem::path& path, const glm::dvec3& centre) {
    std::ifstream in(path);
    if (!in) throw LoadError("pose file " + path.string() + ": cannot be opened");
    Json j;
    try {
        j = Json::parse(in);
    } catch (const Json::exception& e) {
        poseFileError(path, std::string("not JSON (") + e.what() + ")");
    }
    const Json& p = poseObject(j, path);
    glm::dmat4 t(1.0);
    if (p.contains("matrix")) {
        t = matrixOf(p["matrix"], path);
    } else if (p.contains("rotation_deg") && p.contains("translation_mm")) {
        Pose pose;
        pose.rotationDeg = vec3Of(p, "rotation_deg", path);
        pose.translationMm = vec3Of(p, "translation_mm", path);
        const glm::dvec3 c = p.contains("centre_mm") ? vec3Of(p, "centre_mm", path) : centre;
        t = poseMatrix(pose, c);
    } else {
        poseFileError(path, "holds neither \"matrix\" (4x4) nor \"rotation_deg\" and "
                            "\"translation_mm\"");
    }
    try {
        validateRigid(t);
    } catch (const SettingsError& e) {
        poseFileError(path, e.what());
    }
    return t;
}

std::string poseJsonText(const glm::dmat4& T, const glm::dvec3& centre) {
    const Pose pose = poseFromMatrix(T, centre);
    Json m = Json::array();
    for (int r = 0; r < 4; ++r) m.push_back({T[0][r], T[1][r], T[2][r], T[3][r]});
    Json j;
    j["matrix"] = m;
    j["rotation_deg"] = {pose.rotationDeg.x, pose.rotationDeg.y, pose.rotationDeg.z};
    j["translation_mm"] = {pose.translationMm.x, pose.translationMm.y, pose.translationMm.z};
    j["centre_mm"] = {centre.x, centre.y, centre.z};
    j["convention"] =
        "matrix (row-major, patient LPS mm) maps a CT point X to the same anatomy in the X-ray "
        "geometry's frame: the X-ray shows X at pixel P matrix X. matrix X = R (X - centre) + "
        "centre + translation, R = Rz Ry Rx of rotation_deg about the LPS x, y, z axes (x first)";
    return j.dump(2) + "\n";
}

void writePoseJson(const std::filesystem::path& path, const glm::dmat4& T,
                   const glm::dvec3& centre) {
    writeFileAtomic(path, poseJsonText(T, centre));
}

std::vector<glm::dvec3> readTargetsCsv(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw LoadError("targets file " + path.string() + ": cannot be opened");
    std::vector<glm::dvec3> points;
    std::string line;
    int number = 0;
    bool headerSeen = false;
    while (std::getline(in, line)) {
        ++number;
        if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream fields(line);
        glm::dvec3 p;
        std::string rest;
        if (!(fields >> p.x >> p.y >> p.z) || (fields >> rest)) {
            if (points.empty() && !headerSeen &&
                line.find_first_of("0123456789") == std::string::npos) {
                headerSeen = true; // one header line of names
                continue;
            }
            throw LoadError("targets file " + path.string() + " line " + std::to_string(number) +
                            ": expected three numbers x,y,z (LPS mm)");
        }
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw LoadError("targets file " + path.string() + " line " + std::to_string(number) +
                            ": a coordinate is not a finite number");
        points.push_back(p);
    }
    if (points.empty())
        throw LoadError("targets file " + path.string() + ": no points (one x,y,z per line)");
    return points;
}

} // namespace fvr::core
