// The geometry of DICOM X-ray images (XA, RF, DX, CR; classic, multi-frame and Enhanced XA),
// read into C-arms per frame, with every assumption said (xray_geometry.h).
#include <fvr/core/dicom/xray_geometry.h>

#include "dicom_internal.h"
#include "rt_image_internal.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcitem.h>
#include <dcmtk/dcmdata/dcsequen.h>

#include <fvr/core/errors.h>
#include <fvr/core/memory_budget.h>

namespace fvr::core {

namespace dicom_detail {

/** "DistanceSourceToDetector (0018,1110)". */
std::string tagText(const DcmTagKey& tag) {
    return std::string(DcmTag(tag).getTagName()) + " " + tag.toString().c_str();
}

std::string num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

std::string stringOf(DcmItem* item, const DcmTagKey& tag) {
    OFString s;
    if (!item || item->findAndGetOFStringArray(tag, s).bad()) return {};
    std::string r(s.c_str());
    const auto b = r.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    return r.substr(b, r.find_last_not_of(" \t\r\n") - b + 1);
}

/** Every value of a numeric element (DS, IS, FL, FD); empty when absent or empty. Throws naming
 *  the file and the tag when a value is not a finite number. */
std::vector<double> numbersOf(DcmItem* item, const DcmTagKey& tag, const fs::path& file) {
    std::vector<double> out;
    DcmElement* e = nullptr;
    if (!item || item->findAndGetElement(tag, e).bad() || !e || e->getLength() == 0) return out;
    for (unsigned long i = 0; i < e->getVM(); ++i) {
        Float64 v = 0;
        Float32 f = 0; // FL (Enhanced XA's functional groups): DCMTK reads it only as float
        const bool ok = e->ident() == EVR_FL ? item->findAndGetFloat32(tag, f, i).good()
                                             : item->findAndGetFloat64(tag, v, i).good();
        if (e->ident() == EVR_FL) v = f;
        if (!ok || !std::isfinite(v))
            fail(file, tagText(tag) + " '" + stringOf(item, tag) + "' is not a list of numbers");
        out.push_back(v);
    }
    return out;
}

} // namespace dicom_detail

using namespace dicom_detail;

namespace {

constexpr double kDefaultSid = 1000.0; ///< mm, a C-arm's or a table radiograph's
constexpr double kDefaultSodFraction = 0.75; ///< SOD = SID x 0.75 (a cardiac C-arm's)
const char* const kPrivateCreator = "FVR Workstation";

std::optional<double> numberOf(DcmItem* item, const DcmTagKey& tag, const fs::path& file) {
    const std::vector<double> v = numbersOf(item, tag, file);
    if (v.empty()) return std::nullopt;
    return v[0];
}

DcmItem* itemOf(DcmItem* item, const DcmTagKey& seq, unsigned long index = 0) {
    DcmItem* sub = nullptr;
    if (!item || item->findAndGetSequenceItem(seq, sub, long(index)).bad()) return nullptr;
    return sub;
}

/** What one frame states (nothing: the file-level value applies). */
struct FrameStated {
    std::optional<double> sid, sod, primary, secondary;
    std::vector<double> pixelSpacing;
};

/** An Enhanced XA frame's functional groups: per-frame, else shared. */
FrameStated enhancedFrame(DcmDataset* ds, unsigned long frame, const fs::path& file) {
    FrameStated s;
    DcmItem* groups[2] = {itemOf(ds, DCM_PerFrameFunctionalGroupsSequence, frame),
                          itemOf(ds, DCM_SharedFunctionalGroupsSequence)};
    for (DcmItem* g : groups) {
        if (!g) continue;
        if (DcmItem* p = itemOf(g, DCM_PositionerPositionSequence)) {
            if (!s.primary) s.primary = numberOf(p, DCM_PositionerPrimaryAngle, file);
            if (!s.secondary) s.secondary = numberOf(p, DCM_PositionerSecondaryAngle, file);
        }
        if (DcmItem* x = itemOf(g, DCM_XRayGeometrySequence)) {
            if (!s.sid) s.sid = numberOf(x, DCM_DistanceSourceToDetector, file);
            if (!s.sod) s.sod = numberOf(x, DCM_DistanceSourceToIsocenter, file);
        }
        if (DcmItem* px = itemOf(g, DCM_FramePixelDataPropertiesSequence))
            if (s.pixelSpacing.empty())
                s.pixelSpacing = numbersOf(px, DCM_ImagerPixelSpacing, file);
    }
    return s;
}

/** The file-level attributes. */
struct FileStated {
    FrameStated first; ///< top-level values (the first frame's angles)
    std::optional<double> magnification;
    std::vector<double> primaryIncrement, secondaryIncrement, pixelSpacing;
    std::string positionerType, viewPosition, patientOrientation;
};

FileStated fileLevel(DcmDataset* ds, const fs::path& file) {
    FileStated f;
    f.first.sid = numberOf(ds, DCM_DistanceSourceToDetector, file);
    f.first.sod = numberOf(ds, DCM_DistanceSourceToPatient, file);
    f.first.primary = numberOf(ds, DCM_PositionerPrimaryAngle, file);
    f.first.secondary = numberOf(ds, DCM_PositionerSecondaryAngle, file);
    f.first.pixelSpacing = numbersOf(ds, DCM_ImagerPixelSpacing, file);
    f.magnification = numberOf(ds, DCM_EstimatedRadiographicMagnificationFactor, file);
    f.primaryIncrement = numbersOf(ds, DCM_PositionerPrimaryAngleIncrement, file);
    f.secondaryIncrement = numbersOf(ds, DCM_PositionerSecondaryAngleIncrement, file);
    f.pixelSpacing = numbersOf(ds, DCM_PixelSpacing, file);
    f.positionerType = stringOf(ds, DCM_PositionerType);
    f.viewPosition = stringOf(ds, DCM_ViewPosition);
    f.patientOrientation = stringOf(ds, DCM_PatientOrientation);
    return f;
}

/** Appends `w` unless it is there already (frames repeat the same assumption). */
void warnOnce(std::vector<std::string>& warnings, const std::string& w) {
    if (std::find(warnings.begin(), warnings.end(), w) == warnings.end()) warnings.push_back(w);
}

/** An angle of frame k: stated per frame, else the first angle plus the increment (one value:
 *  k times it; one per frame: its k-th entry, C.8.7.5.1.3). */
double frameAngle(const std::optional<double>& perFrame, double first,
                  const std::vector<double>& increment, std::int64_t k) {
    if (perFrame) return *perFrame;
    if (increment.empty()) return first;
    if (increment.size() == 1) return first + double(k) * increment[0];
    return first + increment[static_cast<std::size_t>(k)];
}

void checkIncrement(const std::vector<double>& inc, std::int64_t frames, const DcmTagKey& tag,
                    const fs::path& file) {
    if (inc.size() > 1 && std::int64_t(inc.size()) != frames)
        fail(file, tagText(tag) + " holds " + std::to_string(inc.size()) +
                       " values: expected 1 (a change per frame) or one per frame (" +
                       std::to_string(frames) + ", NumberOfFrames (0028,0008))");
}

/** ViewPosition's C-arm angles for a radiograph without positioner angles (PA: source
 *  posterior, as a C-arm at 0/0; AP: source anterior; LL/RL: detector at the patient's
 *  left/right). */
std::optional<double> viewPositionAngle(const std::string& view) {
    if (view == "PA") return 0.0;
    if (view == "AP") return 180.0;
    if (view == "LL") return 90.0;
    if (view == "RL") return -90.0;
    return std::nullopt;
}

/** Radiographs, whose positioner the DX Positioning module describes (PS3.3 C.8.11.5). */
bool isRadiograph(const std::string& modality) {
    return modality == "DX" || modality == "CR" || modality == "MG" || modality == "IO" ||
           modality == "PX" || modality == "RG";
}

/** Refuses images that are no projection X-ray (CT slices, MR, ...). */
void checkModality(const XrayGeometry& g, const DicomHeader& h) {
    if (h.modality == "XA" || h.modality == "RF" || isRadiograph(h.modality)) return;
    fail(g.file, "Modality (0008,0060) '" + h.modality + "' (" + describeSopClass(h.sopClassUid) +
                     ") is not a projection X-ray: expected XA, RF, DX, CR, RG, MG, IO or PX");
}

/** The angles every frame starts from, with the assumptions said. */
void resolveFirstAngles(const FileStated& f, const std::string& modality, const fs::path& file,
                        double& primary, double& secondary, std::vector<std::string>& warnings) {
    const bool projection = isRadiograph(modality);
    if (f.positionerType == "MAMMOGRAPHIC")
        fail(file, "PositionerType (0018,1508) MAMMOGRAPHIC: its angles are a mammography "
                   "gantry's (PS3.3 C.8.11.7, Mammography Image module), not a C-arm's; not "
                   "supported");
    if (projection && !f.positionerType.empty() && f.positionerType != "CARM" &&
        (f.first.primary || f.first.secondary))
        warnOnce(warnings, "PositionerType (0018,1508) " + f.positionerType +
                               ": the positioner angles are a C-arm's only for CARM (PS3.3 "
                               "C.8.11.5); read as a C-arm's all the same");
    const std::optional<double> fromView = viewPositionAngle(f.viewPosition);
    if (f.first.primary) {
        primary = *f.first.primary;
    } else if (fromView) {
        primary = *fromView;
        warnOnce(warnings, "PositionerPrimaryAngle (0018,1510) missing: ViewPosition (0018,5101) " +
                               f.viewPosition + " gives " + num(primary) + " deg");
    } else {
        primary = 0.0;
        warnOnce(warnings, "PositionerPrimaryAngle (0018,1510) missing: assumed 0 deg (source "
                           "posterior, detector anterior)");
    }
    secondary = f.first.secondary.value_or(0.0);
    if (!f.first.secondary)
        warnOnce(warnings, "PositionerSecondaryAngle (0018,1511) missing: assumed 0 deg");
}

/** SID and SOD of one frame (stated per frame, else file-level), with the assumptions said. */
void resolveDistances(const FrameStated& fr, const FileStated& f, double& sid, double& sod,
                      std::vector<std::string>& warnings) {
    std::optional<double> s = fr.sid ? fr.sid : f.first.sid;
    std::optional<double> o = fr.sod ? fr.sod : f.first.sod;
    const std::optional<double> m = f.magnification;
    const bool useM = m && std::isfinite(*m) && *m > 1.0;
    if (!s && o && useM) {
        s = *o * *m;
        warnOnce(warnings, "DistanceSourceToDetector (0018,1110) missing: DistanceSourceToPatient "
                           "x EstimatedRadiographicMagnificationFactor (0018,1114) = " +
                               num(*s) + " mm");
    } else if (!s) {
        s = kDefaultSid;
        warnOnce(warnings, "DistanceSourceToDetector (0018,1110) missing: assumed " +
                               num(kDefaultSid) + " mm");
    }
    if (!o && useM) {
        o = *s / *m;
        warnOnce(warnings, "DistanceSourceToPatient (0018,1111) missing: assumed SID / "
                           "EstimatedRadiographicMagnificationFactor (0018,1114) " +
                               num(*m) + " = " + num(*o) + " mm");
    } else if (!o) {
        o = *s * kDefaultSodFraction;
        warnOnce(warnings, "DistanceSourceToPatient (0018,1111) missing: assumed SID x " +
                               num(kDefaultSodFraction) + " = " + num(*o) + " mm");
    }
    sid = *s;
    sod = *o;
}

/** The detector pitch: ImagerPixelSpacing (rows, columns), else PixelSpacing, else 1 mm. */
void resolvePitch(XrayGeometry& g, const FrameStated& first, const FileStated& f) {
    std::vector<double> sp = first.pixelSpacing;
    if (sp.size() < 2 && f.pixelSpacing.size() >= 2) {
        sp = f.pixelSpacing;
        g.warnings.push_back("ImagerPixelSpacing (0018,1164) missing: PixelSpacing (0028,0030) " +
                             num(sp[0]) + " x " + num(sp[1]) +
                             " mm read as the detector's pitch (if it is calibrated at the "
                             "patient instead, the DRR's scale differs by SID/SOD)");
    } else if (sp.size() < 2) {
        sp = {1.0, 1.0};
        g.warnings.push_back("ImagerPixelSpacing (0018,1164) and PixelSpacing (0028,0030) "
                             "missing: assumed a detector pitch of 1 x 1 mm");
    }
    if (!(sp[0] > 0.0) || !(sp[1] > 0.0))
        fail(g.file, "ImagerPixelSpacing (0018,1164): expected two spacings > 0, found " +
                         num(sp[0]) + " \\ " + num(sp[1]));
    g.pitchV = sp[0]; // between rows
    g.pitchU = sp[1]; // between columns
}

/** Every frame's C-arm. */
void resolveFrames(XrayGeometry& g, DcmDataset* ds, const DicomHeader& h, const FileStated& f) {
    checkIncrement(f.primaryIncrement, h.frames, DCM_PositionerPrimaryAngleIncrement, g.file);
    checkIncrement(f.secondaryIncrement, h.frames, DCM_PositionerSecondaryAngleIncrement, g.file);
    std::vector<FrameStated> stated(static_cast<std::size_t>(h.frames));
    bool enhancedAngles = false;
    if (h.enhanced)
        for (std::int64_t k = 0; k < h.frames; ++k) {
            stated[std::size_t(k)] = enhancedFrame(ds, static_cast<unsigned long>(k), g.file);
            enhancedAngles = enhancedAngles || stated[std::size_t(k)].primary.has_value();
        }
    FileStated fl = f;
    if (!fl.first.primary && !stated.empty()) fl.first.primary = stated[0].primary;
    if (!fl.first.secondary && !stated.empty()) fl.first.secondary = stated[0].secondary;
    if (fl.first.pixelSpacing.size() < 2 && !stated.empty())
        fl.first.pixelSpacing = stated[0].pixelSpacing;
    double primary0 = 0.0, secondary0 = 0.0;
    resolveFirstAngles(fl, h.modality, g.file, primary0, secondary0, g.warnings);
    resolvePitch(g, fl.first, fl);
    for (std::int64_t k = 0; k < h.frames; ++k) {
        const FrameStated& s = stated[std::size_t(k)];
        CArm arm;
        arm.primaryDeg = frameAngle(s.primary, primary0,
                                    enhancedAngles ? std::vector<double>{} : f.primaryIncrement, k);
        arm.secondaryDeg =
            frameAngle(s.secondary, secondary0,
                       enhancedAngles ? std::vector<double>{} : f.secondaryIncrement, k);
        resolveDistances(s, fl, arm.sid, arm.sod, g.warnings);
        if (!(arm.sid > 0.0) || !(arm.sod > 0.0) || arm.sod >= arm.sid)
            fail(g.file, "frame " + std::to_string(k + 1) + ": source-to-patient " + num(arm.sod) +
                             " mm and source-to-detector " + num(arm.sid) +
                             " mm: expected 0 < SOD < SID");
        g.frames.push_back(arm);
    }
}

/** Isocentre and principal offset from the private tags this project writes. */
void readPrivate(XrayGeometry& g, DcmDataset* ds) {
    const DcmTagKey creator(0x0009, 0x0010);
    if (stringOf(ds, creator) != kPrivateCreator) return;
    const std::vector<double> iso = numbersOf(ds, DcmTagKey(0x0009, 0x1001), g.file);
    const std::vector<double> off = numbersOf(ds, DcmTagKey(0x0009, 0x1002), g.file);
    if (iso.size() == 3) {
        g.isocentreStated = true;
        for (CArm& a : g.frames) a.isocentre = glm::dvec3(iso[0], iso[1], iso[2]);
    }
    if (off.size() == 2) g.principalOffset = glm::dvec2(off[0], off[1]);
}

/** The LPS unit vector a patient-orientation letter names (zero for none). */
glm::dvec3 letterAxis(char c) {
    switch (c) {
    case 'L': return {1, 0, 0};
    case 'R': return {-1, 0, 0};
    case 'P': return {0, 1, 0};
    case 'A': return {0, -1, 0};
    case 'H': return {0, 0, 1};
    case 'F': return {0, 0, -1};
    default: return {0, 0, 0};
    }
}

/** Mirrors the pixels' columns (axis 0) or rows (axis 1) of every frame. */
void mirror(XrayGeometry& g, int axis) {
    const std::size_t W = std::size_t(g.width), H = std::size_t(g.height);
    for (std::size_t f = 0; f < g.frames.size(); ++f) {
        float* p = g.pixels.data() + f * W * H;
        if (axis == 0)
            for (std::size_t r = 0; r < H; ++r) std::reverse(p + r * W, p + (r + 1) * W);
        else
            for (std::size_t r = 0; r < H / 2; ++r)
                std::swap_ranges(p + r * W, p + (r + 1) * W, p + (H - 1 - r) * W);
    }
}

/** PatientOrientation against the camera's u (along a row) and v (down a column), for a file
 *  whose frames all share one pose: a mirrored axis is flipped to match the camera. */
void checkOrientation(XrayGeometry& g, const std::string& orientation) {
    const auto sep = orientation.find('\\');
    if (g.frames.empty()) return;
    for (const CArm& a : g.frames)
        if (a.primaryDeg != g.frames[0].primaryDeg || a.secondaryDeg != g.frames[0].secondaryDeg)
            return; // a rotational run: one orientation cannot hold for every frame
    if (orientation.empty() || sep == std::string::npos || sep == 0 ||
        sep + 1 >= orientation.size()) {
        const ConeCamera c = cArmCamera(g.frames[0], 16, 16, 1.0, 1.0);
        g.warnings.push_back(
            "PatientOrientation (0020,0020) " +
            std::string(orientation.empty() ? "missing" : "'" + orientation + "' unusable") +
            ": the pixels are taken as the camera sees them ('" + patientOrientationLetters(c.u) +
            "\\" + patientOrientationLetters(c.v) + "' at these angles)");
        return;
    }
    ConeCamera c;
    try {
        c = cArmCamera(g.frames[0], 16, 16, 1.0, 1.0);
    } catch (const SettingsError& e) {
        fail(g.file, e.what()); // angles no camera can take (e.g. 1e300 degrees)
    }
    const char letters[2] = {orientation[0], orientation[sep + 1]};
    const glm::dvec3 axes[2] = {c.u, c.v};
    const char* what[2] = {"columns", "rows"};
    for (int k = 0; k < 2; ++k) {
        const double d = glm::dot(axes[k], letterAxis(letters[k]));
        if (d < -0.5) {
            if (!g.pixels.empty()) mirror(g, k);
            g.warnings.push_back("PatientOrientation (0020,0020) '" + orientation +
                                 "': the image's " + what[k] +
                                 " run opposite to the camera's "
                                 "at these angles; " +
                                 what[k] + " mirrored to match it");
        } else if (d <= 0.5) {
            g.warnings.push_back("PatientOrientation (0020,0020) '" + orientation +
                                 "' does not match the camera's " + what[k] +
                                 " at these angles; the pixels are left as they are");
        }
    }
}

/** Tilts of the beam against the detector, which the camera does not model. */
void warnUnmodelled(XrayGeometry& g, DcmDataset* ds) {
    for (const DcmTagKey& t :
         {DCM_DetectorPrimaryAngle, DCM_DetectorSecondaryAngle, DCM_ColumnAngulation}) {
        const std::optional<double> v = numberOf(ds, t, g.file);
        if (v && *v != 0.0)
            g.warnings.push_back(tagText(t) + " " + num(*v) +
                                 " deg ignored: a beam not square to the detector is not "
                                 "modelled (the detector is taken perpendicular to the central "
                                 "ray)");
    }
}

void readPixels(XrayGeometry& g, const DicomHeader& h, DcmFileFormat& ff) {
    if (const std::string why = unsupportedReason(h); !why.empty()) fail(g.file, why);
    const std::uint64_t values = std::uint64_t(h.rows * h.cols) * std::uint64_t(h.frames);
    try {
        checkMemoryFor(values * sizeof(float), g.file.string(),
                       "the pixels of " + std::to_string(h.frames) + " frames as float");
    } catch (const LoadError& e) {
        throw DicomError(e.what());
    }
    const bool invert = h.photometric == "MONOCHROME1";
    std::int64_t nonFinite = 0, padded = 0;
    g.pixels = decodeAllFrames(h, ff, invert, &nonFinite, &padded);
    if (invert)
        g.warnings.push_back("MONOCHROME1: stored values inverted so that larger values are "
                             "brighter");
    if (h.hasModalityLut) g.warnings.push_back("Modality LUT Sequence (0028,3000) applied");
    if (nonFinite > 0)
        g.warnings.push_back(std::to_string(nonFinite) + " non-finite pixel values set to 0");
    if (padded > 0)
        g.warnings.push_back(std::to_string(padded) +
                             " padding pixels (PixelPaddingValue (0028,0120)) set to 0");
}

} // namespace

std::string patientOrientationLetters(const glm::dvec3& direction) {
    const char pos[3] = {'L', 'P', 'H'}, neg[3] = {'R', 'A', 'F'};
    int order[3] = {0, 1, 2};
    std::sort(order, order + 3,
              [&](int a, int b) { return std::abs(direction[a]) > std::abs(direction[b]); });
    std::string s;
    for (int a : order)
        if (std::abs(direction[a]) > 1e-4) s += direction[a] > 0 ? pos[a] : neg[a];
    return s;
}

ConeCamera XrayGeometry::camera(std::size_t frame, const glm::dvec3& isocentre) const {
    if (frame >= frameCount())
        throw SettingsError(file.string() + ": frame " + std::to_string(frame + 1) +
                            " asked for, the file has " + std::to_string(frameCount()));
    if (!beams.empty()) { // an RT Image: its imager about the isocentre
        ConeCamera c = beamCameras[frame];
        if (!isocentreStated) {
            c.source += isocentre;
            c.detectorCentre += isocentre;
        }
        return c;
    }
    CArm arm = frames[frame];
    if (!isocentreStated) arm.isocentre = isocentre;
    return cArmCamera(arm, width, height, pitchU, pitchV, principalOffset);
}

XrayGeometry readXrayGeometry(const std::filesystem::path& path, bool withPixels) {
    std::unique_ptr<DcmFileFormat> ff;
    const DicomHeader h = readHeader(path, &ff);
    DcmDataset* ds = ff->getDataset();
    XrayGeometry g;
    g.file = path;
    g.modality = h.modality;
    g.sopClassUid = h.sopClassUid;
    if (h.rows < 1 || h.cols < 1 || h.rows > 65535 || h.cols > 65535)
        fail(path, "Rows x Columns (0028,0010/0011): expected at least 1 x 1, found " +
                       std::to_string(h.rows) + " x " + std::to_string(h.cols));
    g.width = int(h.cols);
    g.height = int(h.rows);
    if (h.modality == "RTIMAGE" || h.sopClassUid == UID_RTImageStorage) {
        g.modality = "RTIMAGE";
        readRtImageGeometry(g, ds, h.frames);
        if (withPixels) readPixels(g, h, *ff);
        return g;
    }
    checkModality(g, h);
    const FileStated f = fileLevel(ds, path);
    resolveFrames(g, ds, h, f);
    if (f.first.sod && isRadiograph(h.modality))
        g.warnings.push_back(
            "DistanceSourceToPatient (0018,1111) of a " + h.modality +
            " image is measured to the table or detector-side surface nearest the patient (PS3.3 "
            "C.8.11.5), not to an isocentre: the isocentre is placed at that distance");
    readPrivate(g, ds);
    warnUnmodelled(g, ds);
    if (withPixels) readPixels(g, h, *ff);
    checkOrientation(g, f.patientOrientation);
    return g;
}

CArm cArmFromCamera(const ConeCamera& camera, const glm::dvec3& near) {
    camera.validate();
    const glm::dvec3 axis = camera.detectorCentre - camera.source;
    const double sid = glm::length(axis);
    const glm::dvec3 d = axis / sid;
    CArm arm;
    arm.primaryDeg = std::atan2(camera.u.y, camera.u.x) * 180.0 / std::numbers::pi;
    arm.secondaryDeg = std::asin(std::clamp(d.z, -1.0, 1.0)) * 180.0 / std::numbers::pi;
    arm.sid = sid;
    arm.sod = glm::dot(near - camera.source, d);
    arm.isocentre = camera.source + arm.sod * d;
    if (!(arm.sod > 0.0) || arm.sod >= sid)
        throw SettingsError("the point nearest to " + num(near.x) + ", " + num(near.y) + ", " +
                            num(near.z) + " on the principal ray lies " + num(arm.sod) +
                            " mm from the source: a C-arm's isocentre lies between the source "
                            "and the detector (0 < SOD < SID " +
                            num(sid) + " mm)");
    const ConeCamera back = cArmCamera(arm, camera.width, camera.height, camera.pitchU,
                                       camera.pitchV, camera.principalOffset);
    const double tol = 1e-9 * sid;
    if (glm::length(back.source - camera.source) > tol ||
        glm::length(back.detectorCentre - camera.detectorCentre) > tol ||
        glm::length(back.u - camera.u) > 1e-9 || glm::length(back.v - camera.v) > 1e-9)
        throw SettingsError("this camera is no C-arm's: a C-arm's columns run along (cos a, "
                            "sin a, 0) and its rows along u x d (a rolled or tilted detector "
                            "cannot be written as positioner angles)");
    return arm;
}

} // namespace fvr::core
