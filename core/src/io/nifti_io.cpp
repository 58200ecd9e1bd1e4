// NIfTI-1 (.nii/.nii.gz) loader: header, geometry, orientation and voxels.
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

#include <glm/matrix.hpp>

#include <fvr/core/errors.h>

#include "volume_io_internal.h"

namespace fvr::core {

using namespace detail;

// ------------------------------------------------------------------------------------------------
// NIfTI-1

namespace {

struct NiftiHeaderReader {
    const unsigned char* h;
    bool swap;
    template <class T>
    T get(std::size_t offset) const {
        T v;
        std::memcpy(&v, h + offset, sizeof v);
        return swap ? byteSwapped(v) : v;
    }
};

std::optional<ElementType> niftiType(int code) {
    switch (code) {
    case 2: return ElementType::UInt8;
    case 4: return ElementType::Int16;
    case 8: return ElementType::Int32;
    case 16: return ElementType::Float32;
    case 64: return ElementType::Float64;
    case 256: return ElementType::Int8;
    case 512: return ElementType::UInt16;
    case 768: return ElementType::UInt32;
    case 1024: return ElementType::Int64;
    case 1280: return ElementType::UInt64;
    default: return std::nullopt;
    }
}

const char* niftiTypeName(int code) {
    switch (code) {
    case 0: return "DT_UNKNOWN";
    case 1: return "DT_BINARY";
    case 32: return "DT_COMPLEX64";
    case 128: return "DT_RGB24";
    case 255: return "DT_ALL";
    case 1536: return "DT_FLOAT128";
    case 1792: return "DT_COMPLEX128";
    case 2048: return "DT_COMPLEX256";
    case 2304: return "DT_RGBA32";
    default: return "not a NIfTI-1 datatype";
    }
}

/** Whether the file starts with the gzip magic bytes. */
bool isGzipFile(const fs::path& path) {
    std::ifstream f(path, std::ios::binary);
    unsigned char magic[2] = {0, 0};
    f.read(reinterpret_cast<char*>(magic), 2);
    return f.gcount() == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

/** The NIfTI byte stream (zlib reads plain files transparently) and how to name its errors. */
struct NiftiStream {
    GzSource& src;
    bool gz = false;
    std::uint64_t fileSize = 0;

    /** " (gzip: <zlib's error>)", or "" when the data simply ended. */
    std::string readNote() const {
        if (src.error().empty()) return {};
        return (gz ? " (gzip: " : " (") + src.error() + ")";
    }
};

constexpr std::size_t kNiftiHeaderBytes = 348;

/** "; it starts with text: 'hello world...'" when the file's first line is printable text. */
std::string textStartNote(const unsigned char* bytes, std::size_t got) {
    std::size_t n = 0;
    while (n < got && n < 60 && bytes[n] != '\n' && bytes[n] != '\r') {
        if ((bytes[n] < 0x20 && bytes[n] != '\t') || bytes[n] >= 0x7f) return {};
        ++n;
    }
    if (n < 4) return {};
    return "; it starts with text: " +
           quoteValue(std::string_view(reinterpret_cast<const char*>(bytes), n));
}

/** Refuses a file whose header size field `sizeofHdr` (as read) is no NIfTI-1's: a NIfTI-2
 *  file, plain data named .nii.gz, or no NIfTI at all. */
[[noreturn]] void failNotNifti1(const fs::path& path, const NiftiStream& in, std::int32_t sizeofHdr,
                                const unsigned char* h, std::size_t got) {
    if (!in.gz && endsWith(asciiLower(path.filename().string()), ".nii.gz"))
        throw LoadError(path.string() + ": not gzip-compressed data (a .nii.gz file must be gzip)" +
                        textStartNote(h, got));
    if (got < 4)
        fail(path, "sizeof_hdr",
             "expected a 348-byte NIfTI-1 header, found a file of " + std::to_string(got) +
                 " bytes" + in.readNote());
    if (sizeofHdr == 540 || byteSwapped(sizeofHdr) == 540)
        throw LoadError(path.string() +
                        ": a NIfTI-2 file (header size 540): NIfTI-2 is not supported, only "
                        "NIfTI-1 (sizeof_hdr 348); save it as NIfTI-1 to open it");
    throw LoadError(path.string() + ": not a NIfTI file (its header size field (sizeof_hdr) is " +
                    std::to_string(sizeofHdr) +
                    ", expected 348 for NIfTI-1 or 540 for NIfTI-2, in either byte order" +
                    textStartNote(h, got) + ")");
}

/** Reads the 348-byte header into h and checks sizeof_hdr (which gives the byte order) and the
 *  single-file magic. */
NiftiHeaderReader readNiftiHeader(const fs::path& path, const NiftiStream& in,
                                  unsigned char (&h)[kNiftiHeaderBytes]) {
    const std::size_t got = in.src.read(h, sizeof h);
    if (got < sizeof h && !in.src.error().empty())
        fail(path, "header", "expected 348 bytes, found " + std::to_string(got) + in.readNote());
    std::int32_t sizeofHdr = 0;
    if (got >= 4) std::memcpy(&sizeofHdr, h, 4);
    bool swap = false;
    if (got >= 4 && sizeofHdr == 348) {
        swap = false;
    } else if (got >= 4 && byteSwapped(sizeofHdr) == 348) {
        swap = true; // written on a machine of the other byte order
    } else {
        failNotNifti1(path, in, sizeofHdr, h, got);
    }
    if (got < sizeof h)
        fail(path, "header", "expected 348 bytes, found " + std::to_string(got) + in.readNote());

    const std::string_view magic(reinterpret_cast<const char*>(h + 344), 4);
    if (magic == std::string_view("ni1\0", 4))
        fail(path, "magic",
             "expected \"n+1\" (single-file NIfTI-1), found \"ni1\" (a .hdr/.img pair, not "
             "supported)");
    if (magic != std::string_view("n+1\0", 4))
        fail(path, "magic", "expected \"n+1\" (single-file NIfTI-1), found " + quoteValue(magic));
    return NiftiHeaderReader{h, swap};
}

/** dim: 2 or 3 dimensions (or up to 7 with extent 1 beyond the third). */
Dims3 niftiDims(const fs::path& path, const NiftiHeaderReader& r) {
    std::int16_t dim[8];
    for (int i = 0; i < 8; ++i) dim[i] = r.get<std::int16_t>(40 + 2 * i);
    std::string dimText;
    for (int i = 0; i < 8; ++i) {
        if (i) dimText += ' '; // appended piecewise: GCC 12 warns falsely on "" + std::string here
        dimText += std::to_string(dim[i]);
    }
    if (dim[0] < 2 || dim[0] > 7)
        fail(path, "dim[0]",
             "expected 2 or 3 (or 4..7 with one time point), found " + std::to_string(dim[0]) +
                 " (dim = " + dimText + ")");
    for (int i = 4; i <= dim[0]; ++i) {
        if (dim[i] != 1)
            fail(path, "dim[" + std::to_string(i) + "]",
                 "expected 1 (a single 3D volume), found " + std::to_string(dim[i]) +
                     " (dim = " + dimText + ")");
    }
    Dims3 dims{dim[1], dim[2], dim[0] >= 3 ? dim[3] : 1};
    for (int a = 0; a < 3; ++a) {
        if (dims[a] < 1 || dims[a] > kMaxDimPerAxis)
            fail(path, "dim[" + std::to_string(a + 1) + "]",
                 "expected 1.." + std::to_string(kMaxDimPerAxis) + ", found " +
                     std::to_string(dims[a]) + " (dim = " + dimText + ")");
    }
    return dims;
}

ElementType niftiElementType(const fs::path& path, const NiftiHeaderReader& r) {
    const int datatype = r.get<std::int16_t>(70);
    const auto type = niftiType(datatype);
    if (!type)
        fail(path, "datatype",
             "expected a scalar type (2 uint8, 4 int16, 8 int32, 16 float32, 64 float64, 256 int8, "
             "512 uint16, 768 uint32, 1024 int64, 1280 uint64), found " +
                 std::to_string(datatype) + " (" + niftiTypeName(datatype) + ", not supported)");
    return *type;
}

/** mm per unit of xyzt_units' space unit (unknown: mm). */
double niftiUnitToMm(const NiftiHeaderReader& r) {
    const int spaceUnits = r.h[123] & 0x07;
    return spaceUnits == 1 ? 1000.0 : spaceUnits == 3 ? 0.001 : 1.0;
}

/** Spacing (mm) from pixdim[1..3]. */
Vec3 niftiSpacing(const fs::path& path, const NiftiHeaderReader& r, const Dims3& dims,
                  double unitToMm) {
    Vec3 spacing{1.0, 1.0, 1.0};
    for (int a = 0; a < 3; ++a) {
        const float pixdim = r.get<float>(76 + 4 * (a + 1));
        const double p = std::fabs(double(pixdim));
        if (std::isfinite(p) && p > 0.0) {
            spacing[a] = p * unitToMm;
        } else if (dims[a] == 1) {
            spacing[a] = unitToMm; // a single slice: the spacing does not matter
        } else {
            fail(path, "pixdim[" + std::to_string(a + 1) + "]",
                 "expected a finite voxel size > 0, found " + str(pixdim));
        }
    }
    return spacing;
}

/** Where the voxels are and how they scale: vox_offset, scl_slope/scl_inter, sizes. */
struct NiftiData {
    std::uint64_t voxOffset = 0;
    Scaling scaling;
    std::uint64_t dataBytes = 0; ///< voxel bytes
    std::uint64_t required = 0; ///< voxOffset + dataBytes
    std::string layout; ///< "vox_offset 352 + 4 x 4 x 4 voxels x 2 bytes int16"
};

/** Reads vox_offset and the scaling and checks that the file can hold the data. */
NiftiData niftiData(const fs::path& path, const NiftiHeaderReader& r, const NiftiStream& in,
                    const Dims3& dims, ElementType type) {
    NiftiData d;
    const float voxOffsetF = r.get<float>(108);
    if (!std::isfinite(voxOffsetF) || voxOffsetF < 352.0f || voxOffsetF > 1.0e12f ||
        voxOffsetF != std::floor(voxOffsetF))
        fail(path, "vox_offset",
             "expected a whole number of bytes >= 352 (single-file NIfTI-1), found " +
                 str(voxOffsetF));
    d.voxOffset = std::uint64_t(voxOffsetF);
    const float slope = r.get<float>(112);
    const float inter = r.get<float>(116);
    if (std::isfinite(slope) && slope != 0.0f) {
        d.scaling.slope = slope;
        d.scaling.inter = std::isfinite(inter) ? inter : 0.0;
        d.scaling.apply = !(d.scaling.slope == 1.0 && d.scaling.inter == 0.0);
    }

    const std::uint64_t es = elementSize(type);
    d.dataBytes = std::uint64_t(dims[0] * dims[1] * dims[2]) * es;
    d.required = d.voxOffset + d.dataBytes;
    d.layout = "vox_offset " + std::to_string(d.voxOffset) + " + " + std::to_string(dims[0]) +
               " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]) + " voxels x " +
               std::to_string(es) + " bytes " + typeName(type);
    if (!in.gz && in.fileSize < d.required)
        fail(path, "data",
             "expected " + std::to_string(d.required) + " bytes (" + d.layout + "), found " +
                 std::to_string(in.fileSize) + " bytes");
    if (in.gz && d.required > maxInflatedBytes(in.fileSize))
        fail(path, "data",
             "expected " + std::to_string(d.required) + " bytes after decompression (" + d.layout +
                 "), found a gzip file of only " + std::to_string(in.fileSize) +
                 " bytes, which cannot hold that much");
    return d;
}

/** Index axis directions and origin in the NIfTI world frame (RAS, the file's units). */
struct NiftiOrientation {
    glm::dmat3 direction{1.0};
    Vec3 origin{};
    bool stated = true; ///< from the sform or qform (false: identity assumed)
};

/** The sform (sform_code > 0); nullopt when absent or its axes are degenerate. */
std::optional<NiftiOrientation> niftiSform(const fs::path& path, const NiftiHeaderReader& r) {
    if (r.get<std::int16_t>(254) <= 0) return std::nullopt;
    double srow[3][4];
    bool finite = true;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) {
            srow[i][j] = r.get<float>(280 + 16 * i + 4 * j);
            finite = finite && std::isfinite(srow[i][j]);
        }
    if (!finite)
        fail(path, "srow_x/srow_y/srow_z",
             "expected finite numbers (sform_code > 0), found non-finite");
    const auto c0 = normalized({srow[0][0], srow[1][0], srow[2][0]});
    const auto c1 = normalized({srow[0][1], srow[1][1], srow[2][1]});
    auto c2 = normalized({srow[0][2], srow[1][2], srow[2][2]});
    if (c0 && c1 && !c2) c2 = normalized(glm::cross(*c0, *c1));
    if (!c0 || !c1 || !c2) return std::nullopt;
    return NiftiOrientation{{*c0, *c1, *c2}, {srow[0][3], srow[1][3], srow[2][3]}};
}

/** The qform (qform_code > 0): a quaternion rotation, qfac flipping the third axis. */
std::optional<NiftiOrientation> niftiQform(const fs::path& path, const NiftiHeaderReader& r) {
    if (r.get<std::int16_t>(252) <= 0) return std::nullopt;
    double b = r.get<float>(256), c = r.get<float>(260), d = r.get<float>(264);
    const double qx = r.get<float>(268), qy = r.get<float>(272), qz = r.get<float>(276);
    if (!std::isfinite(b) || !std::isfinite(c) || !std::isfinite(d) || !std::isfinite(qx) ||
        !std::isfinite(qy) || !std::isfinite(qz))
        fail(path, "quatern_b/c/d, qoffset_x/y/z",
             "expected finite numbers (qform_code > 0), found non-finite");
    double a = 1.0 - (b * b + c * c + d * d);
    if (a < 1e-7) {
        // b, c, d describe a 180 degree rotation: renormalise them (as nifti1_io does).
        const double n = std::sqrt(b * b + c * c + d * d);
        if (n > 0.0) {
            b /= n;
            c /= n;
            d /= n;
        }
        a = 0.0;
    } else {
        a = std::sqrt(a);
    }
    const double qfac = r.get<float>(76) < 0.0f ? -1.0 : 1.0; // pixdim[0]
    // The rotation matrix as the NIfTI-1 header documents it, written row by row (GLM's
    // constructor takes columns, hence the transpose); qfac flips the third column.
    const glm::dmat3 R = glm::transpose(
        glm::dmat3(a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c), //
                   2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b), //
                   2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b));
    NiftiOrientation o;
    o.direction = R;
    o.direction[2] *= qfac;
    o.origin = {qx, qy, qz};
    return o;
}

/** The Volume's direction and origin (LPS, mm) from the sform (preferred) or the qform;
 *  identity and 0 when neither is usable. */
NiftiOrientation niftiOrientation(const fs::path& path, const NiftiHeaderReader& r,
                                  double unitToMm) {
    auto o = niftiSform(path, r);
    if (!o) o = niftiQform(path, r);
    if (!o) {
        NiftiOrientation assumed{Volume{}.direction, Vec3{0.0, 0.0, 0.0}};
        assumed.stated = false;
        return assumed;
    }
    // NIfTI world coordinates are RAS; the Volume uses LPS like DICOM.
    for (int a = 0; a < 3; ++a) {
        o->direction[a].x = -o->direction[a].x;
        o->direction[a].y = -o->direction[a].y;
    }
    o->origin = {-o->origin[0] * unitToMm, -o->origin[1] * unitToMm, o->origin[2] * unitToMm};
    return *o;
}

/** Skips the extensions between the header and vox_offset. */
void skipNiftiExtensions(const fs::path& path, const NiftiStream& in, const NiftiData& data) {
    std::uint64_t toSkip = data.voxOffset - kNiftiHeaderBytes;
    unsigned char scratch[4096];
    while (toSkip > 0) {
        const std::size_t n = std::size_t(std::min<std::uint64_t>(toSkip, sizeof scratch));
        const std::size_t g = in.src.read(scratch, n);
        toSkip -= g;
        if (g < n) {
            fail(path, "data",
                 "expected " + std::to_string(data.required) + " bytes (" + data.layout +
                     "), found " + std::to_string(data.voxOffset - toSkip) + " bytes" +
                     in.readNote());
        }
    }
}

/** Reads the voxels into vol and, for gzip, checks the stream's trailer. */
void readNiftiVoxels(const fs::path& path, const NiftiStream& in, const NiftiData& data,
                     ElementType type, bool swap, Volume& vol) {
    const std::uint64_t read = readElements(in.src, type, swap, data.scaling,
                                            std::size_t(vol.voxelCount()), vol.voxels.data());
    if (read != data.dataBytes)
        fail(path, "data",
             "expected " + std::to_string(data.required) + " bytes (" + data.layout + "), found " +
                 std::to_string(data.voxOffset + read) + " bytes" + in.readNote());
    if (in.gz) {
        // Reading one byte past the data makes zlib check the gzip trailer (CRC and length) when
        // the data ends the stream, as it does in every .nii.gz: corruption is reported, not
        // hidden.
        unsigned char extra = 0;
        in.src.read(&extra, 1);
        if (!in.src.error().empty())
            fail(path, "data",
                 "gzip stream corrupt or truncated after " + std::to_string(data.required) +
                     " bytes (" + in.src.error() + ")");
    }
}

} // namespace

Volume loadNifti(const fs::path& path) {
    const std::uint64_t fileSize = regularFileSize(path, path, "file");
    const bool gz = isGzipFile(path);
    GzSource src(path); // zlib reads plain files transparently
    if (!src.ok()) fail(path, "file", "cannot open file");
    const NiftiStream in{src, gz, fileSize};

    unsigned char h[kNiftiHeaderBytes];
    const NiftiHeaderReader r = readNiftiHeader(path, in, h);
    const Dims3 dims = niftiDims(path, r);
    const ElementType type = niftiElementType(path, r);
    const double unitToMm = niftiUnitToMm(r);
    const Vec3 spacing = niftiSpacing(path, r, dims, unitToMm);
    validateGeometry(dims, spacing, path.string());
    const NiftiData data = niftiData(path, r, in, dims, type);
    const NiftiOrientation orientation = niftiOrientation(path, r, unitToMm);
    skipNiftiExtensions(path, in, data);

    Volume vol = emptyVolume(dims, spacing, orientation.origin, orientation.direction,
                             volumeName(path), path);
    vol.orientationStated = orientation.stated;
    readNiftiVoxels(path, in, data, type, r.swap, vol);
    return vol;
}

} // namespace fvr::core
