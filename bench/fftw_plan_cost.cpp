// What each FFTW plan of fvr costs to make (FFTW_MEASURE against FFTW_ESTIMATE, no wisdom) and
// to execute, for the plan shapes the preprocessing and the CPU renderer make (the same calls as
// core/src/render/preprocess.cpp and cpu_renderer.cpp): the numbers behind the planning policy
// of fvr/core/render/fftw_planning.h. Reads and writes no wisdom.
//   fvr_fftw_plan_cost [threads]      (default 2)
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

using Make = std::function<fftwf_plan(unsigned flags)>;
using Exec = std::function<void(fftwf_plan)>;

/** One row: planning time and best-of-`reps` execution time for MEASURE and ESTIMATE. */
void row(const std::string& name, int count, const Make& make, const Exec& exec, int reps) {
    double plan[2], run[2];
    const unsigned flags[2] = {FFTW_MEASURE, FFTW_ESTIMATE};
    for (int k = 0; k < 2; ++k) {
        fftwf_forget_wisdom();
        const auto t0 = Clock::now();
        fftwf_plan p = make(flags[k]);
        plan[k] = msSince(t0);
        if (!p) {
            std::printf("%s: FFTW could not plan\n", name.c_str());
            return;
        }
        exec(p);
        run[k] = 1e30;
        for (int r = 0; r < reps; ++r) {
            const auto t = Clock::now();
            exec(p);
            run[k] = std::min(run[k], msSince(t));
        }
        fftwf_destroy_plan(p);
    }
    std::printf("| %-40s | %5d | %9.1f | %7.2f | %9.4f | %9.4f | %6.2f |\n", name.c_str(), count,
                plan[0], plan[1], run[0], run[1], run[1] / run[0]);
    std::fflush(stdout);
}

/** The 3D transform of a padded P0 x P1 x P2 volume: chunks of planes (2D r2c, in place, as the
 *  preprocessing plans them) and the columns (1D along z) as gathered blocks of 16 complex. */
void volumeRows(int P0, int P1, int P2, int threads) {
    const int rs = 2 * (P0 / 2 + 1);
    const std::size_t floats = std::size_t(rs) * P1 * P2;
    float* d = fftwf_alloc_real(floats);
    for (std::size_t i = 0; i < floats; ++i) d[i] = float(i % 13);
    const int perChunk = std::max(1, (P2 + 15) / 16);
    const std::string dims =
        std::to_string(P0) + "x" + std::to_string(P1) + "x" + std::to_string(P2);
    fftwf_plan_with_nthreads(threads);
    for (int howmany : {perChunk, P2 % perChunk}) {
        if (howmany == 0) continue;
        const int n[2] = {P1, P0}, in[2] = {P1, rs}, out[2] = {P1, rs / 2};
        auto* c = reinterpret_cast<fftwf_complex*>(d);
        row(
            dims + " planes r2c x" + std::to_string(howmany),
            howmany == perChunk ? P2 / perChunk : 1,
            [&](unsigned f) {
                return fftwf_plan_many_dft_r2c(2, n, howmany, d, in, 1, rs * P1, c, out, 1,
                                               (rs / 2) * P1, f);
            },
            [&](fftwf_plan p) { fftwf_execute_dft_r2c(p, d, c); }, 3);
    }
    fftwf_plan_with_nthreads(1);
    float* block = fftwf_alloc_real(std::size_t(32) * P2);
    std::memset(block, 0, sizeof(float) * 32 * std::size_t(P2));
    auto* b = reinterpret_cast<fftwf_complex*>(block);
    const int n[1] = {P2};
    row(
        dims + " column block 16 x " + std::to_string(P2), P1 * ((rs / 2 + 15) / 16),
        [&](unsigned f) {
            return fftwf_plan_many_dft(1, n, 16, b, nullptr, 1, P2, b, nullptr, 1, P2, FFTW_FORWARD,
                                       f);
        },
        [&](fftwf_plan p) { fftwf_execute_dft(p, b, b); }, 50);
    fftwf_free(block);
    fftwf_free(d);
}

/** The renderer's inverse of an M x M slice: c2r (FFT spectra) and r2c (Hartley spectra). */
void inverseRows(int M, int threads) {
    const std::size_t half = std::size_t(M) * (M / 2 + 1) * 2, full = std::size_t(M) * M;
    float* a = fftwf_alloc_real(std::max(half, full));
    float* b = fftwf_alloc_real(std::max(half, full));
    std::memset(a, 0, sizeof(float) * std::max(half, full));
    auto* ca = reinterpret_cast<fftwf_complex*>(a);
    auto* cb = reinterpret_cast<fftwf_complex*>(b);
    fftwf_plan_with_nthreads(M >= 512 ? threads : 1);
    const std::string m = std::to_string(M);
    row(
        "inverse c2r " + m + "^2 (per frame)", 1,
        [&](unsigned f) { return fftwf_plan_dft_c2r_2d(M, M, ca, b, f); },
        [&](fftwf_plan p) { fftwf_execute_dft_c2r(p, ca, b); }, 50);
    row(
        "inverse r2c " + m + "^2 (Hartley, per frame)", 1,
        [&](unsigned f) { return fftwf_plan_dft_r2c_2d(M, M, a, cb, f); },
        [&](fftwf_plan p) { fftwf_execute_dft_r2c(p, a, cb); }, 50);
    row(
        "inverse DHT " + m + "^2 (FFTW_DHT, before)", 1,
        [&](unsigned f) { return fftwf_plan_r2r_2d(M, M, a, a, FFTW_DHT, FFTW_DHT, f); },
        [&](fftwf_plan p) { fftwf_execute_r2r(p, a, a); }, 50);
    fftwf_free(a);
    fftwf_free(b);
}

} // namespace

int main(int argc, char** argv) {
    const int threads = argc > 1 ? std::max(1, std::atoi(argv[1])) : 2;
    fftwf_init_threads();
    fftwf_set_timelimit(3.0); // as the workstation
    std::printf("FFTW %s, %d threads, time limit 3 s; times in ms; count: executions per "
                "transform\n\n",
                fftwf_version, threads);
    std::printf("| plan | count | MEASURE plan | ESTIMATE plan | MEASURE run | ESTIMATE run | "
                "run E/M |\n|---|---|---|---|---|---|---|\n");
    volumeRows(512, 512, 140, threads); // Philips CT at oversampling 1 (fvr-render's default)
    inverseRows(512, threads);
    volumeRows(256, 256, 256, threads); // 256^3 phantom
    volumeRows(640, 640, 175, threads); // Philips CT at 1.25 (the workstation's default)
    inverseRows(256, threads);
}
