// Speed, memory and growth of every registered estimator (issue 9), with Google Benchmark.
//
// Walks: simulated step-level hip walks (tarrio-circle: waist IMU 50 Hz, 9 anchors, one RSS
// reading per anchor every 0.5 s ≈ 18 readings/s) and foot-INS walks (prieto-laps: foot IMU
// 100 Hz) of 1 min, 10 min, 16 min, 1 h and 10 h, plus the real Plaza1 walk. Each benchmark is
// "<estimator>/<walk>"; counters: walk_s, realtime_x (walk seconds per wall second),
// peak_rss_mb (getrusage of this process: run one benchmark per process for memory figures,
// as tools/run_benchmarks.sh does) and every diagnostic the estimator reports (e.g.
// ceres_iterations, update latency percentiles).
//
//   ./build/tools/bench_estimators --benchmark_filter='fg-batch/hip-16min'
//   ./build/tools/bench_estimators --wg_summarize DIR   # DIR/*.json → DIR/bench.json + bench.md
//   ./build/tools/bench_estimators --wg_ipin ../shared/datasets/ipin2023_t3 \
//       --benchmark_filter='^fg-batch/ipin'    # the IPIN trials, BLE alone and with WiFi
#include <sys/resource.h>
#include <sys/utsname.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "walkgraph/convert.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/logging.h"
#include "walkgraph/simulate.h"

namespace {

namespace fs = std::filesystem;

struct WalkSpec {
  std::string name;
  std::string scenario;  // empty: a walk directory, or an IPIN log
  double minutes = 0.0;
  std::string dir;
  // Non-empty: dir is the IPIN 2023 Track 3 folder and this trial is converted from it
  // (`convert ipin --known-start`, with `--wifi` when ipin_wifi).
  std::string ipin_trial;
  bool ipin_wifi = false;
};

// --wg_ipin DIR: the shared IPIN 2023 Track 3 trials as well, BLE alone and with their WiFi
// access points (issue 44's speed target: fg-batch with WiFi under 2x its BLE-only time).
std::string& IpinDir() {
  static std::string dir;
  return dir;
}

std::vector<WalkSpec> WalkSpecs() {
  std::vector<WalkSpec> specs;
  for (double minutes : {1.0, 10.0, 16.0, 60.0, 600.0}) {
    const std::string m = std::to_string(static_cast<int>(minutes)) + "min";
    specs.push_back({"hip-" + m, "tarrio-circle", minutes, ""});
    specs.push_back({"foot-" + m, "prieto-laps", minutes, ""});
  }
  specs.push_back({"plaza1", "", 0.0, std::string(WALKGRAPH_SOURCE_DIR) + "/datasets/plaza1"});
  if (IpinDir().empty()) return specs;
  for (const char* trial : {"01", "05", "21", "52"}) {
    for (bool wifi : {false, true}) {
      specs.push_back({std::string("ipin") + trial + (wifi ? "-wifi" : "-ble"), "", 0.0, IpinDir(),
                       trial, wifi});
    }
  }
  return specs;
}

walkgraph::StatusOr<walkgraph::Walk> MakeWalk(const WalkSpec& spec) {
  if (!spec.ipin_trial.empty()) {
    walkgraph::ConvertOptions o;
    o.known_start = true;
    o.ipin_wifi = spec.ipin_wifi;
    return walkgraph::Convert(
        "ipin",
        {spec.dir + "/IPIN2023_T3_TrainingTrial" + spec.ipin_trial + "_repetition01.txt",
         spec.dir + "/BLE_Locations.csv"},
        o);
  }
  if (spec.scenario.empty()) return walkgraph::ReadWalk(spec.dir);
  return walkgraph::SimulateScenario(
      spec.scenario, 1, YAML::Load("{duration_s: " + std::to_string(spec.minutes * 60.0) + "}"));
}

// Walks are made once per process, on first use.
const walkgraph::Walk* GetWalk(const WalkSpec& spec, std::string* error) {
  static std::map<std::string, std::unique_ptr<walkgraph::Walk>> cache;
  static std::mutex mu;
  std::lock_guard<std::mutex> lock(mu);
  auto it = cache.find(spec.name);
  if (it != cache.end()) return it->second.get();
  walkgraph::StatusOr<walkgraph::Walk> walk = MakeWalk(spec);
  if (!walk.ok()) {
    *error = walk.status().message();
    return nullptr;
  }
  auto owned = std::make_unique<walkgraph::Walk>(std::move(walk).value());
  const walkgraph::Walk* ptr = owned.get();
  cache[spec.name] = std::move(owned);
  return ptr;
}

double PeakRssMb() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // kB on Linux
}

// A /proc/self/status field in MB (VmRSS: resident now; VmHWM: its high-water mark); -1 if
// unavailable.
double ProcStatusMb(const std::string& field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024.0;
  }
  return -1.0;
}

// Resets VmHWM to the current RSS (Linux: "5" to /proc/self/clear_refs), so that after a run
// VmHWM − VmRSS(before) is what the run itself added at its peak (the walk already in memory
// excluded). False where the kernel does not offer it.
bool ResetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

void RunEstimator(benchmark::State& state, const std::string& id, const WalkSpec& spec) {
  std::string error;
  const walkgraph::Walk* walk = GetWalk(spec, &error);
  if (walk == nullptr) {
    state.SkipWithError(error.c_str());
    return;
  }
  auto est = walkgraph::EstimatorRegistry::Builtin().Create(id);
  if (!est.ok() || !(*est)->CheckApplicable(*walk).ok()) {
    state.SkipWithError("not applicable to this walk");
    return;
  }
  std::map<std::string, double> diagnostics;
  const bool run_peak = ResetPeakRss();
  const double rss_before_mb = ProcStatusMb("VmRSS");
  for (auto _ : state) {
    auto result = (*est)->Run(*walk);
    if (!result.ok()) {
      state.SkipWithError(result.status().message().c_str());
      return;
    }
    diagnostics = result->diagnostics;
    for (const auto& [k, v] : result->timings) diagnostics[k] = v;
    benchmark::DoNotOptimize(result->trajectory.points.data());
  }
  const double walk_s = walk->EndTime() - walk->StartTime();
  state.counters["walk_s"] = walk_s;
  state.counters["realtime_x"] =
      benchmark::Counter(walk_s, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["peak_rss_mb"] = PeakRssMb();
  if (run_peak && rss_before_mb >= 0.0) {
    state.counters["run_peak_rss_mb"] = ProcStatusMb("VmHWM") - rss_before_mb;
  }
  for (const auto& [k, v] : diagnostics) state.counters[k] = v;
}

// --------------------------------------------------------------------------- summary

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

int Summarize(const std::string& dir) {
  nlohmann::json merged;
  merged["benchmarks"] = nlohmann::json::array();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".json" && e.path().filename() != "bench.json") {
      files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    std::ifstream in(f);
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      std::cerr << f << ": not JSON: " << e.what() << "\n";
      return 1;
    }
    if (!merged.contains("context")) merged["context"] = j["context"];
    for (auto& b : j["benchmarks"]) merged["benchmarks"].push_back(b);
  }
  // One row per benchmark; then the log-log growth slope per estimator and walk family.
  std::ostringstream md;
  md << std::fixed;
  md << "| estimator | walk | walk [min] | wall [s] | × real time | peak RSS [MB] | "
        "run's own peak [MB] | notes |\n";
  md << "|---|---|---:|---:|---:|---:|---:|---|\n";
  std::map<std::string, std::vector<std::pair<double, double>>> growth;  // (walk_s, wall_s)
  for (const auto& b : merged["benchmarks"]) {
    const std::string name = b.value("name", "");
    const auto slash = name.find('/');
    const std::string id = name.substr(0, slash);
    std::string walk = slash == std::string::npos ? "" : name.substr(slash + 1);
    walk = walk.substr(0, walk.find('/'));
    if (b.value("error_occurred", false)) {
      md << "| " << id << " | " << walk << " | | | | | | skipped: " << b.value("error_message", "")
         << " |\n";
      continue;
    }
    const double wall = b.value("real_time", 0.0) / (b.value("time_unit", "ns") == "s"    ? 1.0
                                                     : b.value("time_unit", "ns") == "ms" ? 1e3
                                                     : b.value("time_unit", "ns") == "us" ? 1e6
                                                                                          : 1e9);
    const double walk_s = b.value("walk_s", 0.0);
    std::ostringstream notes;
    for (const auto& [k, v] : b.items()) {
      if (k == "ceres_iterations" || k.rfind("update_latency", 0) == 0 ||
          k.rfind("latency", 0) == 0 || k.rfind("window_max", 0) == 0) {
        notes << k << "=" << std::setprecision(4) << v.get<double>() << " ";
      }
    }
    md << "| " << id << " | " << walk << " | " << std::setprecision(1) << walk_s / 60.0 << " | "
       << std::setprecision(3) << wall << " | " << std::setprecision(0) << walk_s / wall << " | "
       << std::setprecision(1) << b.value("peak_rss_mb", 0.0) << " | "
       << b.value("run_peak_rss_mb", 0.0) << " | " << notes.str() << "|\n";
    const std::string family = walk.substr(0, walk.find('-'));
    if (family == "hip" || family == "foot")
      growth[id + " (" + family + ")"].push_back({walk_s, wall});
  }
  md << "\n| estimator (walk family) | log-log slope of wall time vs walk length |\n|---|---:|\n";
  for (auto& [key, pts] : growth) {
    if (pts.size() < 2) continue;
    // Least-squares slope of log(wall) on log(walk_s).
    double mx = 0, my = 0;
    for (auto& [x, y] : pts) {
      mx += std::log(x);
      my += std::log(y);
    }
    mx /= pts.size();
    my /= pts.size();
    double sxy = 0, sxx = 0;
    for (auto& [x, y] : pts) {
      sxy += (std::log(x) - mx) * (std::log(y) - my);
      sxx += (std::log(x) - mx) * (std::log(x) - mx);
    }
    md << "| " << key << " | " << std::setprecision(2) << (sxx > 0 ? sxy / sxx : 0.0) << " |\n";
  }
  struct utsname u;
  uname(&u);
  const nlohmann::json context = merged.contains("context") && merged["context"].is_object()
                                     ? merged["context"]
                                     : nlohmann::json::object();
  md << "\nMachine: " << u.sysname << " " << u.release << " " << u.machine << ", "
     << context.value("num_cpus", 0) << " CPUs at " << context.value("mhz_per_cpu", 0)
     << " MHz; one benchmark per process, one thread.\n";
  std::ofstream(fs::path(dir) / "bench.json") << merged.dump(2) << "\n";
  std::ofstream(fs::path(dir) / "bench.md") << md.str();
  std::cout << md.str();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  walkgraph::InitLogging(argv[0]);
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "--wg_summarize") == 0) return Summarize(argv[i + 1]);
  }
  for (int i = 1; i + 1 < argc; ++i) {  // --wg_ipin DIR: taken out before Google Benchmark's
    if (std::strcmp(argv[i], "--wg_ipin") != 0) continue;
    IpinDir() = argv[i + 1];
    for (int j = i; j + 2 < argc; ++j) argv[j] = argv[j + 2];
    argc -= 2;
    break;
  }
  for (const std::string& id : walkgraph::EstimatorRegistry::Builtin().Ids()) {
    for (const WalkSpec& spec : WalkSpecs()) {
      auto* b = benchmark::RegisterBenchmark(
          (id + "/" + spec.name).c_str(),
          [id, spec](benchmark::State& st) { RunEstimator(st, id, spec); });
      b->Unit(benchmark::kMillisecond)->UseRealTime();
      if (spec.minutes >= 60.0)
        b->Iterations(1);
      else
        b->MinTime(0.5);
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
