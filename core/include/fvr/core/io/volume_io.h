#pragma once
/** Volume file loaders: MetaImage (.mhd/.mha), NIfTI-1 (.nii/.nii.gz) and headerless raw.
 *  Every loader validates the header before allocating and throws LoadError with a message
 *  naming the file, the field, what was expected and what was found. */
#include <cstdint>
#include <filesystem>

#include <fvr/core/volume.h>

namespace fvr::core {

enum class ElementType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64
};

/** Bytes per element of `t`. */
std::size_t elementSize(ElementType t);
/** Parses "int16", "uint8", "float32", ... (also MetaImage's MET_SHORT etc.); throws SettingsError.
 */
ElementType parseElementType(const std::string& name);

/** Description of a headerless raw file. */
struct RawSpec {
    Dims3 dims{0, 0, 0};
    Vec3 spacing{1.0, 1.0, 1.0};
    ElementType type = ElementType::Int16;
    bool bigEndian = false;
    std::uint64_t headerBytes = 0; ///< bytes skipped at the start of the file
};

/** True for the names loadVolume reads: .mhd, .mha, .nii, .nii.gz (any case). */
bool isVolumeFileName(const std::filesystem::path& path);

/** Loads a volume, choosing the reader by extension (.mhd, .mha, .nii, .nii.gz).
 *  Throws LoadError for unknown extensions and for every malformed file. */
Volume loadVolume(const std::filesystem::path& path);

/** MetaImage: all element types, both byte orders, ElementDataFile as LOCAL, one file, a LIST,
 *  or the `pattern start end step` form; HeaderSize; ElementSpacing/Offset/TransformMatrix. */
Volume loadMetaImage(const std::filesystem::path& path);

/** NIfTI-1 single file, optionally gzip-compressed: scl_slope/scl_inter applied, spacing from
 *  pixdim (xyzt_units to mm), direction from sform (preferred) or qform. */
Volume loadNifti(const std::filesystem::path& path);

/** Headerless raw file with explicit geometry; the file length must match exactly. */
Volume loadRaw(const std::filesystem::path& path, const RawSpec& spec);

} // namespace fvr::core
