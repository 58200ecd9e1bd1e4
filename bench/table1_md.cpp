/**
 * fvr_table1_md TABLE1.json: the GPU Table 1 in Markdown from the Google Benchmark JSON of
 * fvr_bench_gpu (--benchmark_format=json or --benchmark_out). One section per volume size N and
 * transform (FFT, FHT), rows M×M, in the layout of Table 1 of Viola et al. 2004:
 *   stages: slice fps per kernel (slice pass unfused) and the inverse 2D transform's fps
 *           (kernel-independent: the median over the kernels);
 *   frame:  end-to-end fps per kernel (slice fused into the row pass, display mapping into the
 *           last: GPU timer queries) and, after the slash, wall-clock fps of frames issued back to
 *           back.
 * Only what the JSON holds appears (a filtered run gives a smaller table). Where a benchmark ran
 * more than once (repetitions) a cell is the median of its runs. Part of the hardware bench kit
 * (make gpu-kit), where Python may be missing. Exit status 2 on bad input, naming the file.
 */
#include <algorithm>
#include <cstdio>
#include <exception>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

namespace {

using Json = nlohmann::json;

/** BM_Gpu<Stages|Frame>/N<n>/<fft|fht>/M<m>/<kernel>[/iterations:I/real_time] */
struct Key {
    int n = 0;
    std::string transform;
    int m = 0;
    std::string kernel;
    bool operator<(const Key& o) const {
        return std::tie(n, transform, m, kernel) < std::tie(o.n, o.transform, o.m, o.kernel);
    }
};

struct Table {
    std::map<Key, std::map<std::string, std::vector<double>>> stages, frame;
    std::vector<std::string> kernels; // in the order of the JSON (the bench's allKernels order)
    std::set<std::pair<int, std::string>> sections;
    std::set<int> sizes;
};

bool parseName(const std::string& name, std::string& bench, Key& k) {
    std::vector<std::string> parts;
    std::stringstream ss(name);
    for (std::string p; std::getline(ss, p, '/');) parts.push_back(p);
    if (parts.size() < 5 || parts[1].size() < 2 || parts[3].size() < 2) return false;
    if (parts[1][0] != 'N' || parts[3][0] != 'M') return false;
    try {
        k = {std::stoi(parts[1].substr(1)), parts[2], std::stoi(parts[3].substr(1)), parts[4]};
    } catch (const std::exception&) {
        return false;
    }
    bench = parts[0];
    return true;
}

void addRun(Table& t, const Json& b) {
    std::string bench;
    Key k;
    if (!b.contains("name") || !parseName(b["name"].get<std::string>(), bench, k)) return;
    if (b.value("run_type", std::string("iteration")) != "iteration") return;
    if (b.value("error_occurred", false)) return;
    if (bench != "BM_GpuStages" && bench != "BM_GpuFrame") return;
    auto& dest = bench == "BM_GpuStages" ? t.stages : t.frame;
    for (const char* c : {"slice_ms", "inverse_ms", "gpu_ms", "wall_ms"})
        if (b.contains(c) && b[c].is_number()) dest[k][c].push_back(b[c].get<double>());
    if (std::find(t.kernels.begin(), t.kernels.end(), k.kernel) == t.kernels.end())
        t.kernels.push_back(k.kernel);
    t.sections.insert({k.n, k.transform});
    t.sizes.insert(k.m);
}

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

/** fps from ms with thousands separators ("12,345"); "–" where not measured. */
std::string fps(double ms) {
    if (!(ms > 0)) return "–";
    const long long f = static_cast<long long>(1000.0 / ms + 0.5);
    const std::string digits = std::to_string(f);
    std::string s;
    for (std::size_t i = 0; i < digits.size(); ++i) {
        if (i > 0 && (digits.size() - i) % 3 == 0) s += ',';
        s += digits[i];
    }
    return s;
}

double cell(const std::map<Key, std::map<std::string, std::vector<double>>>& m, const Key& k,
            const char* counter) {
    const auto it = m.find(k);
    if (it == m.end()) return 0.0;
    const auto c = it->second.find(counter);
    return c == it->second.end() ? 0.0 : median(c->second);
}

std::string row(const std::vector<std::string>& cells) {
    std::string s = "|";
    for (const auto& c : cells) s += " " + c + " |";
    return s + "\n";
}

std::string stagesTable(const Table& t, int n, const std::string& transform) {
    std::vector<std::string> head{"M×M"}, align{"---:"};
    for (const auto& k : t.kernels) head.push_back(k + " slice fps"), align.push_back("---:");
    head.push_back(std::string(transform == "fht" ? "IFHT" : "IFFT") + " 2D fps");
    align.push_back("---:");
    std::string out = row(head) + row(align);
    for (int m : t.sizes) {
        std::vector<std::string> cells{std::to_string(m) + "×" + std::to_string(m)};
        std::vector<double> inverse;
        for (const auto& k : t.kernels) {
            const Key key{n, transform, m, k};
            cells.push_back(fps(cell(t.stages, key, "slice_ms")));
            if (const double inv = cell(t.stages, key, "inverse_ms"); inv > 0)
                inverse.push_back(inv);
        }
        cells.push_back(fps(median(inverse)));
        out += row(cells);
    }
    return out;
}

std::string frameTable(const Table& t, int n, const std::string& transform) {
    std::vector<std::string> head{"M×M"}, align{"---:"};
    for (const auto& k : t.kernels)
        head.push_back(k + " fps (GPU / wall)"), align.push_back("---:");
    std::string out = row(head) + row(align);
    for (int m : t.sizes) {
        std::vector<std::string> cells{std::to_string(m) + "×" + std::to_string(m)};
        for (const auto& k : t.kernels) {
            const Key key{n, transform, m, k};
            cells.push_back(fps(cell(t.frame, key, "gpu_ms")) + " / " +
                            fps(cell(t.frame, key, "wall_ms")));
        }
        out += row(cells);
    }
    return out;
}

std::string markdown(const Table& t, const Json& context) {
    std::string out = "# GPU Table 1 (fvr_bench_gpu)\n\n";
    out += "- GL renderer: " + context.value("gl_renderer", std::string("(not recorded)")) + "\n";
    out += "- Host: " + context.value("host_name", std::string("?")) + ", " +
           std::to_string(context.value("num_cpus", 0)) + " CPUs, run " +
           context.value("date", std::string("?")) + "\n";
    out += "- 3D Shepp-Logan phantom N³, mu values, no oversampling; 64 views about a tilted "
           "axis; 8 untimed frames first, then the median of the timed ones.\n- Stages: slice pass "
           "unfused and the inverse 2D transform, GPU timer queries. "
           "Frame: slice fused into the row pass, display mapping to an 8-bit texture; GPU timer "
           "fps / wall-clock fps of 16 frames issued back to back.\n";
    for (const auto& [n, transform] : t.sections) {
        const std::string name = transform == "fht" ? "FHT" : "FFT";
        out += "\n## " + name + ", N = " + std::to_string(n) + " (volume " + std::to_string(n) +
               "^3)\n\n### Stages\n\n" + stagesTable(t, n, transform) + "\n### Frame\n\n" +
               frameTable(t, n, transform);
    }
    return out;
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: fvr_table1_md TABLE1.json > table1.md\n");
        return 2;
    }
    try {
        std::ifstream in(argv[1]);
        if (!in) throw std::runtime_error("cannot open the file");
        const Json j = Json::parse(in);
        if (!j.contains("benchmarks") || !j["benchmarks"].is_array())
            throw std::runtime_error("no \"benchmarks\" array (not Google Benchmark JSON)");
        Table t;
        for (const auto& b : j["benchmarks"]) addRun(t, b);
        if (t.sections.empty()) throw std::runtime_error("no BM_GpuStages/BM_GpuFrame results");
        std::fputs(markdown(t, j.value("context", Json::object())).c_str(), stdout);
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr_table1_md: %s: %s\n", argv[1], e.what());
        return 2;
    }
}
