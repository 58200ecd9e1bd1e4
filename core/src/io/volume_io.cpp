// Volume loaders: MetaImage, NIfTI-1 and headerless raw.
//
// Every loader works in the same order: parse and validate the header, work out exactly which
// bytes of which files hold the voxels and check those files are long enough, and only then
// allocate the volume and read it in bulk (1 MiB chunks converted to float). Nothing about the
// input is trusted before it has been checked, so garbage files end in a LoadError, not a crash
// or a huge allocation.
//
// The loaders live in metaimage_io.cpp and nifti_io.cpp; the helpers they share in
// volume_io_text.cpp and volume_io_bytes.cpp (declared in volume_io_internal.h). This file holds
// the public entry points and the headerless raw loader.
#include <fvr/core/io/volume_io.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fvr/core/errors.h>

#include "volume_io_internal.h"

namespace fvr::core {

using namespace detail;

// ------------------------------------------------------------------------------------------------
// Public API

std::size_t elementSize(ElementType t) {
    switch (t) {
    case ElementType::Int8:
    case ElementType::UInt8: return 1;
    case ElementType::Int16:
    case ElementType::UInt16: return 2;
    case ElementType::Int32:
    case ElementType::UInt32:
    case ElementType::Float32: return 4;
    case ElementType::Int64:
    case ElementType::UInt64:
    case ElementType::Float64: return 8;
    }
    throw SettingsError("element type: expected one of int8..float64, found enum value " +
                        std::to_string(int(t)));
}

ElementType parseElementType(const std::string& name) {
    struct Entry {
        const char* name;
        ElementType type;
    };
    // MetaIO sizes: MET_LONG/MET_ULONG are 4 bytes, MET_LONG_LONG/MET_ULONG_LONG 8 bytes.
    static constexpr Entry kNames[] = {
        {"int8", ElementType::Int8},           {"uint8", ElementType::UInt8},
        {"int16", ElementType::Int16},         {"uint16", ElementType::UInt16},
        {"int32", ElementType::Int32},         {"uint32", ElementType::UInt32},
        {"int64", ElementType::Int64},         {"uint64", ElementType::UInt64},
        {"float32", ElementType::Float32},     {"float64", ElementType::Float64},
        {"float", ElementType::Float32},       {"double", ElementType::Float64},
        {"met_char", ElementType::Int8},       {"met_uchar", ElementType::UInt8},
        {"met_short", ElementType::Int16},     {"met_ushort", ElementType::UInt16},
        {"met_int", ElementType::Int32},       {"met_uint", ElementType::UInt32},
        {"met_long", ElementType::Int32},      {"met_ulong", ElementType::UInt32},
        {"met_long_long", ElementType::Int64}, {"met_ulong_long", ElementType::UInt64},
        {"met_float", ElementType::Float32},   {"met_double", ElementType::Float64},
    };
    const std::string l = asciiLower(trimSpace(name));
    for (const Entry& e : kNames)
        if (l == e.name) return e.type;
    throw SettingsError(
        "element type: expected int8, uint8, int16, uint16, int32, uint32, int64, uint64, "
        "float32, float64 or MET_CHAR, MET_UCHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, "
        "MET_LONG, MET_ULONG, MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT, MET_DOUBLE, found " +
        quoteValue(name));
}

bool isVolumeFileName(const fs::path& path) {
    const std::string l = asciiLower(path.filename().string());
    return endsWith(l, ".mhd") || endsWith(l, ".mha") || endsWith(l, ".nii") ||
           endsWith(l, ".nii.gz");
}

Volume loadVolume(const fs::path& path) {
    const std::string l = asciiLower(path.filename().string());
    if (endsWith(l, ".mhd") || endsWith(l, ".mha")) return loadMetaImage(path);
    if (endsWith(l, ".nii") || endsWith(l, ".nii.gz")) return loadNifti(path);
    fail(path, "format",
         "unknown volume format: expected .mhd, .mha, .nii or .nii.gz, found " +
             quoteValue(path.extension().string()));
}

// ------------------------------------------------------------------------------------------------
// Raw

Volume loadRaw(const fs::path& path, const RawSpec& spec) {
    validateGeometry(spec.dims, spec.spacing, path.string());
    const std::uint64_t es = elementSize(spec.type);
    const std::int64_t voxelCount = spec.dims[0] * spec.dims[1] * spec.dims[2];
    const std::uint64_t dataBytes = std::uint64_t(voxelCount) * es;
    const std::uint64_t size = regularFileSize(path, path, "file");
    const std::string layout = "headerBytes " + std::to_string(spec.headerBytes) + " + " +
                               std::to_string(spec.dims[0]) + " x " + std::to_string(spec.dims[1]) +
                               " x " + std::to_string(spec.dims[2]) + " voxels x " +
                               std::to_string(es) + " bytes " + typeName(spec.type);
    if (spec.headerBytes > std::numeric_limits<std::uint64_t>::max() - dataBytes ||
        size != spec.headerBytes + dataBytes) {
        const std::string expected =
            spec.headerBytes > std::numeric_limits<std::uint64_t>::max() - dataBytes
                ? std::string("more than 2^64")
                : std::to_string(spec.headerBytes + dataBytes);
        fail(path, "file size",
             "expected " + expected + " bytes (" + layout + "), found " + std::to_string(size) +
                 " bytes");
    }
    FileSource src(path, spec.headerBytes);
    if (!src.ok()) fail(path, "file", "cannot open file");
    Volume vol = emptyVolume(spec.dims, spec.spacing, Vec3{0, 0, 0}, Volume{}.direction,
                             path.stem().string(), path);
    vol.orientationStated = false; // raw data carry none
    const std::uint64_t read = readElements(src, spec.type, spec.bigEndian, Scaling{},
                                            std::size_t(voxelCount), vol.voxels.data());
    if (read != dataBytes)
        fail(path, "data",
             "expected " + std::to_string(dataBytes) + " data bytes from byte " +
                 std::to_string(spec.headerBytes) + ", found " + std::to_string(read) + " bytes");
    return vol;
}

} // namespace fvr::core
