#pragma once
/** The volume's 3D spectrum as the renderers read it: 4 bytes per padded voxel. */
#include <complex>
#include <cstdint>
#include <memory>
#include <optional>

#include <fvr/core/render/kernels.h>

#include <fvr/core/volume.h>

namespace fvr::core {

/** How voxel values are mapped before the transform. */
enum class ValueMapping {
    Raw, ///< stored values (HU for CT): line integrals in value x mm
    Mu, ///< linear attenuation relative to water, max(0, 1 + HU/1000): line integrals in mm
    MuBone ///< bone-enhanced attenuation (xray.h, mapValue): line integrals in mm
};
/** Spectrum representation and matching inverse 2D transform. */
enum class TransformKind {
    Fft, ///< complex half spectrum (Hermitian), inverse 2D complex-to-real FFT
    Fht ///< real 3D Hartley transform; inverse 2D Hartley transform (CPU: Re - Im of one
        ///< real-to-complex FFT; GPU: separable passes and the paper's eq. 4 correction)
};

const char* valueMappingName(ValueMapping m);
ValueMapping parseValueMapping(
    const std::string& s); ///< "raw" | "mu" | "mu-bone"; throws SettingsError
const char* transformName(TransformKind t);
TransformKind parseTransform(const std::string& s); ///< "fft" | "fht"; throws SettingsError

/** Frees buffers from fftwf_malloc. */
struct FftwFree {
    void operator()(float* p) const;
};
using FftwBuffer = std::unique_ptr<float[], FftwFree>;
/** fftwf_malloc'ed, SIMD-aligned float buffer; throws std::bad_alloc. */
FftwBuffer allocateFftw(std::size_t floats);

/**
 * Spectrum of a zero-padded, centred volume (the centre voxel position (N-1)/2 on the FFT origin,
 * any half-voxel remainder folded in as a phase), unnormalised (FFTW's sign -1 forward):
 * G[k] = sum_x f[x] exp(-2 pi i k.(x - (N-1)/2) / P).
 *
 * Storage is one buffer of rowStride() * P1 * P2 floats, row (y, z) at (y + P1 z) * rowStride():
 *  - Fft: complex G for kx = 0..P0/2 (interleaved re, im); other kx via G[-k] = conj G[k].
 *  - Fht: real Hartley H[k] = Re G[k] - Im G[k] for kx = 0..P0-1.
 * Frequencies are signed indices, periodic with P per axis.
 */
struct Spectrum {
    TransformKind kind = TransformKind::Fft;
    ValueMapping mapping = ValueMapping::Raw;
    ValueUnits sourceUnits = ValueUnits::Unknown;
    Dims3 volumeDims{0, 0, 0};
    Vec3 spacing{1, 1, 1};
    Dims3 padded{0, 0, 0};
    std::string name;
    /** Set when the volume was divided by this kernel's Fourier transform before the 3D
     *  transform (deapodization): the renderers then accept only this kernel. */
    std::optional<Kernel> deapodizedFor;
    /** Every mapped voxel value is >= 0 (attenuation, or raw data without negative values), so
     *  every true line integral is too (RenderParams::nonNegative). */
    bool nonNegative = false;
    FftwBuffer data;

    std::int64_t rowStride() const { return 2 * (padded[0] / 2 + 1); }
    std::size_t floatCount() const { return std::size_t(rowStride() * padded[1] * padded[2]); }
    std::size_t bytes() const { return floatCount() * sizeof(float); }

    /** G at integer signed frequency (any integers, wrapped periodically). */
    std::complex<double> valueAt(std::int64_t kx, std::int64_t ky, std::int64_t kz) const;
    /** Hartley value Re G - Im G at integer signed frequency. */
    double hartleyAt(std::int64_t kx, std::int64_t ky, std::int64_t kz) const;
};

} // namespace fvr::core
