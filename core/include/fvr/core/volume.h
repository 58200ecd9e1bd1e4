#pragma once
/** The volume model shared by every layer: float voxels on a regular grid. */
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/mat3x3.hpp>

#include <fvr/core/vec3.h>

namespace fvr::core {

using Dims3 = std::array<std::int64_t, 3>;

/** What the voxel values mean. */
enum class ValueUnits { Unknown, HounsfieldUnits, LinearAttenuationRelWater, Intensity };

const char* unitsName(ValueUnits u);

/** Largest accepted number of voxels per axis and in total (checked before any allocation). */
inline constexpr std::int64_t kMaxDimPerAxis = 16384;
inline constexpr std::int64_t kMaxVoxels = std::int64_t(2048) * 2048 * 2048;

/**
 * A scalar volume. Voxel (x, y, z) (x = column, fastest; y = row; z = slice) is stored at
 * index x + nx * (y + ny * z). Spacing in mm per index axis. Origin is the physical (patient,
 * LPS for DICOM) position of voxel (0,0,0); direction[a] (column a of the matrix) is the unit
 * vector of index axis a in that frame (identity when the file carries no orientation): the
 * physical offset of index offset i is direction * (i * spacing), and `x * direction` (x times the
 * matrix, that is transpose(direction) x) takes a physical offset back onto the index axes.
 */
struct Volume {
    Dims3 dims{0, 0, 0};
    Vec3 spacing{1.0, 1.0, 1.0};
    Vec3 origin{0.0, 0.0, 0.0};
    glm::dmat3 direction{1.0};
    ValueUnits units = ValueUnits::Unknown;
    /** False when the file carries no orientation (a MetaImage without TransformMatrix, a NIfTI
     *  with neither sform nor qform, raw data): `direction` is then the identity by assumption
     *  (index axes x, y, z = patient left, posterior, superior) and front ends must say so. */
    bool orientationStated = true;
    std::string name;
    std::vector<float> voxels;

    std::int64_t voxelCount() const { return dims[0] * dims[1] * dims[2]; }
    std::size_t index(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return std::size_t(x + dims[0] * (y + dims[1] * z));
    }
    float at(std::int64_t x, std::int64_t y, std::int64_t z) const {
        return voxels[index(x, y, z)];
    }
    /** Physical extent N*s per axis (mm). */
    Vec3 extent() const {
        return {dims[0] * spacing[0], dims[1] * spacing[1], dims[2] * spacing[2]};
    }
    /** Minimum and maximum voxel value (0,0 for an empty volume). */
    std::pair<float, float> valueRange() const;
};

/** Throws SettingsError/LoadError naming `source` if dims or spacing are unusable
 *  (dims < 1, above kMaxDimPerAxis, total above kMaxVoxels, spacing <= 0 or not finite). */
void validateGeometry(const Dims3& dims, const Vec3& spacing, const std::string& source);

} // namespace fvr::core
