#pragma once
/** The beams of a DICOM RT Plan (PS3.3 A.20, RT Beams Module C.8.8.14) as treatment beams
 *  (geometry/treatment_beam.h), each with the geometry of its first control point:
 *   - Beam Sequence (300A,00B0): Beam Number (300A,00C0), Beam Name (300A,00C2), Source-Axis
 *     Distance (300A,00B4) (type 3: 1000 mm assumed, with a warning, when absent), Treatment
 *     Delivery Type (300A,00CE), Referenced Patient Setup Number (300C,006A);
 *   - its Control Point Sequence (300A,0111), first item: Gantry Angle (300A,011E), Beam
 *     Limiting Device Angle (300A,0120), Patient Support Angle (300A,0122), Isocenter Position
 *     (300A,012C, patient LPS mm);
 *   - Patient Setup Sequence (300A,0180): the setup whose Patient Setup Number (300A,0182) the
 *     beam references (the only setup when the beam references none) gives Patient Position
 *     (0018,5100).
 *  Later control points (arcs, collimator or couch moves during the beam), table-top pitch,
 *  roll and eccentric rotation and the imager's own offsets are not read. An RT Ion Plan (Ion
 *  Beam Sequence) is refused. */
#include <filesystem>
#include <string>
#include <vector>

#include <fvr/core/geometry/treatment_beam.h>

namespace fvr::core {

struct RtPlanBeam {
    int number = 0; ///< Beam Number
    std::string name; ///< Beam Name (may be empty)
    std::string deliveryType; ///< TREATMENT, SETUP, ... (may be empty)
    /** The first control point's angles, the isocentre, the SAD and the patient position;
     *  sid is TreatmentBeam's default (the plan has no imager). */
    TreatmentBeam beam;
    bool sadStated = true; ///< false: SourceAxisDistance absent, 1000 mm assumed
};

struct RtPlan {
    std::filesystem::path file;
    std::string label; ///< RT Plan Label (300A,0002)
    std::vector<RtPlanBeam> beams; ///< in the file's order
    std::vector<std::string> warnings; ///< each assumption, naming the tag
};

/** Reads an RT Plan's beams. Throws DicomError (a LoadError) naming the file and the problem:
 *  unreadable, not an RT Plan (its SOP class named), no Beam Sequence or an empty one, and for
 *  each beam (named by its number) a missing or non-numeric Beam Number, Control Point Sequence,
 *  gantry, collimator or couch angle, Isocenter Position (three numbers), a Source-Axis Distance
 *  that is not a positive number, or a patient setup that is missing, ambiguous or has no
 *  Patient Position, or one a couch cannot hold (see parsePatientPosition). */
RtPlan readRtPlan(const std::filesystem::path& path);

/** readRtPlan(path).beams. */
std::vector<RtPlanBeam> readRtPlanBeams(const std::filesystem::path& path);

} // namespace fvr::core
