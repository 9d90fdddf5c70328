// walkgraph: the command-line shell over the library. Parses arguments, calls the library,
// prints. Every failure prints "walkgraph: <message>" on stderr and exits 1; an interrupted
// run (SIGINT, SIGTERM, SIGHUP, SIGQUIT) exits 128 + the signal, its outputs left as they were
// (walkgraph/output.h).
#include <glog/logging.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include <CLI/CLI.hpp>

#include "config/reader.h"
#include "eval/pcrb_yaml.h"
#include "io/plausibility.h"
#include "stance/stance_yaml.h"
#include "util/text.h"
#include "walkgraph/compare.h"
#include "walkgraph/config.h"
#include "walkgraph/convert.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/logging.h"
#include "walkgraph/output.h"
#include "walkgraph/parallel.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/radio.h"
#include "walkgraph/simulate.h"
#include "walkgraph/stance.h"
#include "walkgraph/study.h"

#include "mpi_job.h"

namespace {

using walkgraph::Status;

// What every output of this run is written with: --force, the command line for the marker, and
// the run's inputs (set by each command).
walkgraph::OutputOptions g_output;

// The processes of this run (mpi_job.h): one, or the ranks of an MPI job.
const walkgraph_cli::MpiJob* g_job = nullptr;

// Whether the ranks of an MPI job share this run's work (set by main): the command line runs a
// study, or a scenario's Monte Carlo comparison (compare --scenario NAME), and there is more
// than one rank. Other commands run on rank 0 alone.
bool g_ranks_share = false;

bool IsSharedRun(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-v" || arg == "--verbosity") {
      ++i;
      continue;
    }
    if (!arg.empty() && arg[0] == '-') continue;
    if (arg == "study") return !(i + 1 < argc && std::string(argv[i + 1]) == "merge");
    if (arg != "compare") return false;
    for (int j = i + 1; j < argc; ++j) {
      const std::string a = argv[j];
      if (a.rfind("--scenario=", 0) == 0 || (a == "--scenario" && j + 1 < argc)) return true;
    }
    return false;
  }
  return false;
}

int Fail(const Status& s) {
  std::cerr << "walkgraph: " << s.message() << "\n";
  if (s.code() == walkgraph::StatusCode::kCancelled) return 128 + walkgraph::CancelSignal();
  return 1;
}

// Reads a walk and prints what it holds that is unusual but accepted (io.h
// PlausibilityWarnings: e.g. holes in the IMU stream, which the estimators bridge instead of
// integrating across); compare also counts them in results.json.
walkgraph::StatusOr<walkgraph::Walk> ReadWalk(const std::string& dir) {
  auto walk = walkgraph::ReadWalk(dir);
  if (!walk.ok()) return walk;
  for (const std::string& w : walkgraph::PlausibilityWarnings(*walk)) {
    std::cerr << "walkgraph: warning: " << dir << "/" << w << "\n";
  }
  return walk;
}

// An error about a --config file's contents, prefixed with the file's path (the library names the
// estimator and the line, but it does not know the file).
Status InConfig(const std::string& path, const Status& s) {
  if (s.ok() || path.empty() || s.message().rfind(path, 0) == 0) return s;
  return Status(s.code(), path + ": " + s.message());
}

// After a command's outputs are written: a signal that came during the write (too late to keep
// the old output) still ends the run as interrupted.
int Finish(int rc) {
  if (rc == 0 && walkgraph::CancelRequested()) {
    std::cerr << "walkgraph: interrupted (signal " << walkgraph::CancelSignal()
              << ") after the output was complete\n";
    return 128 + walkgraph::CancelSignal();
  }
  return rc;
}

// SIGINT/SIGTERM/SIGHUP/SIGQUIT: ask the library to stop; when no output is being written
// there is nothing of ours on disk to clean up, so end at once.
extern "C" void OnSignal(int signal_number) {
  walkgraph::RequestCancel(signal_number);
  if (!walkgraph::OutputInProgress()) ::_exit(128 + signal_number);
}

void InstallSignalHandlers() {
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) ::sigaction(sig, &action, nullptr);
}

// Last resorts: an exception escaping a thread, or a failed CHECK inside a dependency, end the
// run with one message and exit 1 (never an abort's 134).
[[noreturn]] void OnTerminate() {
  std::fputs("walkgraph: internal error: unexpected exception; no output was written\n", stderr);
  ::_exit(1);
}
[[noreturn]] void OnCheckFailure() {
  std::fputs("walkgraph: internal error: a check inside a dependency failed (see above)\n", stderr);
  ::_exit(1);
}

std::string CommandLine(int argc, char** argv) {
  std::string s;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a.size() > 200) a = a.substr(0, 200) + "...";
    if (a.find_first_of(" \t'\"") != std::string::npos) a = "'" + a + "'";
    s += (i ? " " : "") + a;
  }
  return s;
}

// A seed: a decimal integer in [0, 2^64 - 1] (CLI11 would wrap "-1" to 2^64 - 1).
std::string ParseSeed(const std::string& text, uint64_t* seed) {
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, *seed);
  if (text.empty() || text[0] == '-' || text[0] == '+' || ec != std::errc() || ptr != end) {
    return "--seed: expected a decimal integer in [0, 18446744073709551615], found '" +
           (text.size() > 40 ? text.substr(0, 40) + "..." : text) + "'";
  }
  return "";
}

// --estimators "a, b,c": ids without empty entries; spaces around an id are ignored.
walkgraph::StatusOr<std::vector<std::string>> SplitIds(const std::string& text) {
  std::vector<std::string> ids;
  if (walkgraph::internal::Trim(text).empty()) return ids;
  for (const std::string& field : walkgraph::internal::Split(text, ',')) {
    std::string id = walkgraph::internal::Trim(field);
    if (id.empty()) {
      return walkgraph::InvalidArgument(
          "--estimators: empty estimator id in the list; expected comma-separated ids such as "
          "fg-batch,tarrio-kf (see walkgraph list)");
    }
    ids.push_back(std::move(id));
  }
  return ids;
}

// Reads --config FILE.yaml: either the options of one estimator, or (for compare) a map from
// estimator id to its options.
walkgraph::StatusOr<YAML::Node> LoadConfig(const std::string& path) {
  if (path.empty()) return YAML::Node();
  return walkgraph::LoadYamlFile(path);
}

int RunValidate(const std::string& walk_dir) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  std::cout << walk_dir << ": OK (" << walk->anchors.size() << " anchors, " << walk->imu.size()
            << " IMU, " << walk->rss.size() << " RSS, " << walk->ranges.size() << " range, "
            << walk->odometry.size() << " odometry, " << walk->truth.size() << " truth samples"
            << (walk->waypoints.empty()
                    ? ""
                    : ", " + std::to_string(walk->waypoints.size()) + " waypoints")
            << "; " << walk->EndTime() - walk->StartTime() << " s)\n";
  return 0;
}

// Fails at once when --out would be refused at the end (see walkgraph/output.h).
Status Preflight(const std::string& out, walkgraph::OutputKind kind,
                 std::vector<std::string> inputs) {
  g_output.inputs = std::move(inputs);
  return walkgraph::CheckOutputTarget(out, kind, g_output);
}

int RunConvert(const std::string& format, const std::vector<std::string>& sources,
               const walkgraph::ConvertOptions& options, const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, sources); !s.ok()) return Fail(s);
  std::vector<std::string> warnings;
  auto walk = walkgraph::Convert(format, sources, options, &warnings);
  if (!walk.ok()) return Fail(walk.status());
  for (const std::string& w : warnings) std::cerr << "walkgraph: warning: " << w << "\n";
  const Status s = walkgraph::WriteWalk(*walk, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << "\n";
  return 0;
}

// Fits RSS = A − 10·η·log10(d/d0) to a walk's RSS readings against its truth (positions
// linearly interpolated between truth samples; readings outside the truth's span are skipped;
// the distance is 3-D when the truth has a height, else horizontal to the anchor's x-y with the
// anchor's height against 0). With `floors` (--floors; truth and anchors with floors): the
// receiver at its truth floor's height, the anchor at Walk::AnchorHeightM, and the floor loss
// per floor crossed fitted with A and η (FitPathLoss) — the model of the step-graph estimators
// when floor_loss_db > 0, not of the planar filters (their A, η come from the plain fit). Prints a
// `radio:` block for walk.yaml (global fit) and the fit per anchor as comments. Meant to calibrate
// one walk's path loss for use on a different walk.
int RunFitPathLoss(const std::string& walk_dir, bool floors) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  const auto& truth = walk->truth;
  if (truth.size() < 2) return Fail(walkgraph::FailedPrecondition("fit-path-loss: no truth"));
  std::vector<walkgraph::PathLossObservation> obs;
  for (const walkgraph::RssSample& r : walk->rss) {
    const auto it =
        std::lower_bound(truth.begin(), truth.end(), r.t_s,
                         [](const walkgraph::TruthSample& t, double x) { return t.t_s < x; });
    if (it == truth.end() || it == truth.begin() || r.t_s < truth.front().t_s) continue;
    const auto& b = *it;
    const auto& a = *(it - 1);
    const double w = b.t_s > a.t_s ? (r.t_s - a.t_s) / (b.t_s - a.t_s) : 0.0;
    Eigen::Vector3d p = (1 - w) * a.position_m + w * b.position_m;
    if (!a.has_z || !b.has_z) p.z() = 0.0;
    const walkgraph::Anchor* anchor = nullptr;
    for (const auto& an : walk->anchors) {
      if (an.id == r.anchor_id) anchor = &an;
    }
    if (anchor == nullptr) continue;
    Eigen::Vector3d anchor_m = anchor->position_m;
    const std::optional<int> floor = w < 0.5 ? a.floor : b.floor;  // floors do not interpolate
    int crossed = 0;
    if (floors && floor && anchor->floor) {
      p.z() = *floor * walk->meta.storey_height_m;
      anchor_m.z() = walk->AnchorHeightM(*anchor);
      crossed = std::abs(*floor - *anchor->floor);
    }
    obs.push_back({r.anchor_id, (anchor_m - p).norm(), r.rss, crossed});
  }
  const auto units = walk->meta.radio.units;
  const double d0 = walk->meta.radio.path_loss.d0_m;
  auto fit = walkgraph::FitPathLoss(obs, units, d0);
  if (!fit.ok()) return Fail(fit.status());
  // The printed block goes into a walk.yaml: a fit that walk.yaml would refuse is an error.
  std::string absurd = walkgraph::internal::CheckPathLoss(fit->params, units, {});
  if (absurd.empty() && !(fit->params.floor_loss_db >= 0.0 && fit->params.floor_loss_db <= 100.0)) {
    absurd = "floor_loss_db " + walkgraph::internal::Num(fit->params.floor_loss_db) +
             " outside [0, 100] dB";
  }
  if (!absurd.empty()) {
    return Fail(walkgraph::FailedPrecondition(
        "fit-path-loss " + walk_dir + ": the fit over " + std::to_string(fit->num_observations) +
        " readings is not a usable path-loss model: " + absurd +
        ". Expected RSS that falls with the distance to the anchors: check anchors.csv's "
        "positions and ids, radio.units, and that the truth is in the anchors' frame"));
  }
  std::printf("# fit-path-loss %s: %d readings inside the truth's span\n", walk_dir.c_str(),
              fit->num_observations);
  auto per = walkgraph::FitPathLossPerAnchor(obs, units, d0);
  if (per.ok()) {
    for (const auto& f : *per) {
      std::printf("# anchor %d: A %.2f eta %.3f sigma %.2f (n = %d)\n", f.anchor_id, f.params.A_dbm,
                  f.params.eta, f.params.sigma_db, f.num_observations);
    }
  }
  std::printf("A_dbm: %.3f\neta: %.4f\nsigma_db: %.3f\nfloor_loss_db: %.3f\ncalibrated: true\n",
              fit->params.A_dbm, fit->params.eta, fit->params.sigma_db, fit->params.floor_loss_db);
  return 0;
}

// smooth --config takes compare's shape, {id: {option: value}} (the section of --estimator
// used), or one estimator's options alone, {option: value}: a map whose keys are all estimator
// ids is the former.
walkgraph::StatusOr<YAML::Node> SmoothOptions(const YAML::Node& config, const std::string& id,
                                              const std::string& path) {
  if (!config.IsMap() || config.size() == 0) return config;
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const auto& kv : config) {
    if (!kv.first.IsScalar() || registry.Find(kv.first.Scalar()) == nullptr) return config;
  }
  if (!config[id]) {
    return walkgraph::InvalidArgument(
        path + ":" + std::to_string(config.Mark().line + 1) +
        ": a file of sections by estimator id (compare's shape) without a section for '" + id +
        "'");
  }
  return config[id];
}

int RunSmooth(const std::string& walk_dir, const std::string& id, const std::string& config_path,
              const std::string& out, const std::string& ipin_out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFile, {walk_dir, config_path}); !s.ok()) {
    return Fail(s);
  }
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  auto file = LoadConfig(config_path);
  if (!file.ok()) return Fail(file.status());
  auto config = SmoothOptions(*file, id, config_path);
  if (!config.ok()) return Fail(config.status());
  auto est = walkgraph::EstimatorRegistry::Builtin().Create(id, *config);
  if (!est.ok()) return Fail(InConfig(config_path, est.status()));
  const Status applicable = (*est)->CheckApplicable(*walk);
  if (!applicable.ok()) return Fail(applicable);
  auto result = (*est)->Run(*walk);
  if (!result.ok()) return Fail(result.status());
  const Status s = walkgraph::WriteTumTrajectory(result->trajectory, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << " (" << result->trajectory.size() << " poses)\n";
  if (!ipin_out.empty()) {
    const Status si = walkgraph::WriteIpinSubmission(*walk, result->trajectory, ipin_out, g_output);
    if (!si.ok()) return Fail(si);
    std::cout << "wrote " << ipin_out << " (IPIN submission, 2 Hz from t = 0)\n";
  }
  return 0;
}

struct CompareArgs {
  std::string walk_dir;
  std::string scenario;
  int runs = 1;
  uint64_t seed = 1;
  int threads = 1;
  std::string ids;
  std::string config_path;
  std::string scenario_config_path;
  bool align_se2 = false;
  bool keep_diverged = false;
  double score_from_s = 0.0;
  std::string out;
};

struct PcrbArgs {
  std::string scenario, scenario_config, config;
  int runs = 1;
  uint64_t seed = 1;
  int threads = 1;
};

// compare --config: a map from estimator id to that estimator's options.
Status ConfigsById(const YAML::Node& config, const std::string& path,
                   std::map<std::string, walkgraph::Config>* out) {
  if (!config.IsDefined() || config.IsNull()) return Status::Ok();
  const auto line = [&](const YAML::Node& n) { return std::to_string(n.Mark().line + 1); };
  if (!config.IsMap()) {
    return walkgraph::InvalidArgument(
        path + ":" + line(config) +
        ": expected a map from estimator id to its options, e.g. {tarrio-kf: {sigma_p_m: 0.5}}");
  }
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const auto& kv : config) {
    if (!kv.first.IsScalar() || registry.Find(kv.first.Scalar()) == nullptr) {
      std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "(not a word)";
      if (key.size() > 80) key = key.substr(0, 80) + "...";
      return walkgraph::InvalidArgument(
          path + ":" + line(kv.first) + ": '" + key +
          "' is not an estimator id (see walkgraph list): compare --config takes one section "
          "per estimator, {estimator id: {option: value}}, as smooth --config also does");
    }
    // Created once here so that a bad option fails now, naming the file.
    auto estimator = registry.Create(kv.first.Scalar(), kv.second);
    if (!estimator.ok()) return InConfig(path, estimator.status());
    (*out)[kv.first.Scalar()] = kv.second;
  }
  return Status::Ok();
}

// "42 s", "3 min 07 s", "2 h 05 min", "12.5 days".
std::string Duration(double s) {
  char text[64];
  if (s < 60) {
    std::snprintf(text, sizeof(text), "%.0f s", s);
  } else if (s < 3600) {
    std::snprintf(text, sizeof(text), "%d min %02d s", int(s / 60), int(s) % 60);
  } else if (s < 2 * 86400) {
    std::snprintf(text, sizeof(text), "%d h %02d min", int(s / 3600), int(s / 60) % 60);
  } else {
    std::snprintf(text, sizeof(text), "%.1f days", s / 86400);
  }
  return text;
}

// Seconds between two progress lines in a log: 10, or WALKGRAPH_PROGRESS_INTERVAL_S (a
// number >= 0; for tests, which set 0 to see every line without a slow run).
double ProgressInterval() {
  const char* text = std::getenv("WALKGRAPH_PROGRESS_INTERVAL_S");
  if (text == nullptr || *text == '\0') return 10.0;
  char* end = nullptr;
  const double s = std::strtod(text, &end);
  return *end == '\0' && std::isfinite(s) && s >= 0.0 ? s : 10.0;
}

// "3" or "2.4" (a fraction of the units: an estimator part-way through its walk).
std::string Count(double done) {
  char text[32];
  const double whole = std::floor(done);
  if (done == whole) {
    std::snprintf(text, sizeof(text), "%.0f", done);
  } else {
    std::snprintf(text, sizeof(text), "%.1f", std::floor(done * 10) / 10);
  }
  return text;
}

// Progress of a long run on stderr with a time estimate (elapsed / done × the rest): on a
// terminal a bar redrawn in place (at most 10 times a second); else (a batch job's log) a plain
// line every ProgressInterval() s, the first after one interval (a short run prints nothing) and
// one at the end if any came before. `done` may be fractional (compare on one walk: estimators
// done plus the running one's fraction). The calls may come from several threads.
std::function<void(double, int)> MakeProgress(const std::string& prefix, const std::string& unit) {
  struct State {
    std::string prefix, unit;
    bool tty = false, printed = false;
    std::chrono::duration<double> interval;
    std::chrono::steady_clock::time_point start, last;
    std::mutex mutex;
  };
  auto st = std::make_shared<State>();
  st->prefix = prefix;
  st->unit = unit;
  st->tty = ::isatty(STDERR_FILENO) != 0;
  st->interval = std::chrono::duration<double>(st->tty ? 0.1 : ProgressInterval());
  st->start = st->last = std::chrono::steady_clock::now();
  return [st](double done, int total) {
    std::lock_guard<std::mutex> lock(st->mutex);
    const auto now = std::chrono::steady_clock::now();
    const bool end = done >= total;
    if (now - st->last < st->interval && !(end && st->printed)) return;
    st->last = now;
    st->printed = true;
    const double elapsed = std::chrono::duration<double>(now - st->start).count();
    const std::string left =
        done > 0 && !end ? ", about " + Duration(elapsed / done * (total - done)) + " left" : "";
    const double share = total > 0 ? std::min(done / total, 1.0) : 1.0;
    if (st->tty) {
      constexpr int kWidth = 30;
      const int filled = int(share * kWidth);
      std::string bar(filled, '#');
      bar.append(kWidth - filled, '-');
      std::fprintf(stderr, "\r%s[%s] %s/%d %s, %s elapsed%s\033[K", st->prefix.c_str(), bar.c_str(),
                   Count(done).c_str(), total, st->unit.c_str(), Duration(elapsed).c_str(),
                   left.c_str());
      if (end) std::fprintf(stderr, "\n");
    } else {
      std::fprintf(stderr, "%s%s/%d %s (%d%%), %s elapsed%s\n", st->prefix.c_str(),
                   Count(done).c_str(), total, st->unit.c_str(), int(share * 100),
                   Duration(elapsed).c_str(), left.c_str());
    }
    std::fflush(stderr);
  };
}

// What compare runs, from its arguments.
struct PreparedCompare {
  walkgraph::CompareOptions options;
  walkgraph::ScenarioCompareOptions scenario;
  walkgraph::MonteCarloOptions mc;
};

// Checks compare's arguments and reads its inputs (and, with `preflight`, checks --out).
Status PrepareCompare(const CompareArgs& args, bool preflight, PreparedCompare* p) {
  if (args.walk_dir.empty() == args.scenario.empty()) {
    return walkgraph::InvalidArgument("compare: give either WALK or --scenario NAME");
  }
  if (!args.walk_dir.empty() && args.runs != 1) {
    return walkgraph::InvalidArgument(
        "compare: --runs needs --scenario (a recorded walk is the same on every run)");
  }
  if (!args.scenario_config_path.empty() && args.scenario.empty()) {
    return walkgraph::InvalidArgument("compare: --scenario-config needs --scenario");
  }
  if (preflight) {
    WG_RETURN_IF_ERROR(Preflight(args.out, walkgraph::OutputKind::kFolder,
                                 {args.walk_dir, args.config_path, args.scenario_config_path}));
  }
  walkgraph::CompareOptions& options = p->options;
  auto ids = SplitIds(args.ids);
  if (!ids.ok()) return ids.status();
  options.estimator_ids = *ids;
  options.alignment = args.align_se2 ? walkgraph::Alignment::kSE2 : walkgraph::Alignment::kNone;
  options.score_from_s = args.score_from_s;
  options.divergence.keep_in_figures = args.keep_diverged;
  options.compact = true;  // trajectories and errors stream to disk as each estimator finishes
  auto config = LoadConfig(args.config_path);
  if (!config.ok()) return config.status();
  WG_RETURN_IF_ERROR(ConfigsById(*config, args.config_path, &options.configs));
  if (!args.scenario_config_path.empty()) {
    auto overrides = walkgraph::LoadYamlFile(args.scenario_config_path);
    if (!overrides.ok()) return overrides.status();
    p->scenario.overrides = *overrides;
    p->scenario.overrides_origin = args.scenario_config_path;
  }
  p->mc.runs = args.runs;
  p->mc.seed = args.seed;
  p->mc.threads = args.threads;
  return Status::Ok();
}

int WriteCompare(const CompareArgs& args, const walkgraph::Comparison& comparison) {
  std::cout << walkgraph::FormatComparisonTable(comparison);
  const Status s = walkgraph::WriteComparison(comparison, args.out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << args.out
            << "/{report.html,results.json,errors.csv,truth.tum,trajectories/}\n";
  return 0;
}

// ------------------------------------------------- compare --scenario under MPI
// The ranks share the Monte Carlo runs round robin (run r on rank r % N: deterministic, and
// balanced within one run); each runs its share on its --threads (the library's
// CompareScenarioShare) and keeps each finished run's bytes in a temporary file. Then rank 0
// takes the runs in run order, one round of N runs at a time (run k·N + r from rank r, one
// Gather per round), through the library's ScenarioRunMerger and writes the outputs: the same
// bytes as one process, with memory that does not grow with the runs.

constexpr char kOtherRankFailed[] = "stopped: another rank failed";

// Collective: OK when `local` is OK on every rank. Otherwise rank 0 gets the first failure in
// rank order (to report) and the other ranks kOtherRankFailed.
Status AgreeAcrossRanks(const walkgraph_cli::MpiJob& job, const Status& local) {
  if (job.AllOk(local.ok())) return Status::Ok();
  const std::string mine =
      local.ok() ? "" : std::to_string(static_cast<int>(local.code())) + " " + local.message();
  auto gathered = job.Gather(mine);
  if (job.rank() != 0) return walkgraph::Cancelled(kOtherRankFailed);
  if (!gathered.ok()) return gathered.status();
  for (const std::string& g : *gathered) {
    if (g.empty()) continue;
    const size_t space = g.find(' ');
    const int code = std::atoi(g.substr(0, space).c_str());
    return Status(static_cast<walkgraph::StatusCode>(code), g.substr(space + 1));
  }
  return walkgraph::InternalError("a rank failed without saying why");
}

// A rank's finished runs on disk (an anonymous temporary file), read back in the order written.
class RunSpill {
 public:
  RunSpill() : file_(std::tmpfile()) {}
  ~RunSpill() {
    if (file_ != nullptr) std::fclose(file_);
  }
  RunSpill(const RunSpill&) = delete;
  RunSpill& operator=(const RunSpill&) = delete;

  Status Append(const std::string& bytes) {
    const uint64_t n = bytes.size();
    if (file_ == nullptr || std::fwrite(&n, sizeof(n), 1, file_) != 1 ||
        std::fwrite(bytes.data(), 1, n, file_) != n) {
      return walkgraph::IoError("compare: cannot keep a finished run in a temporary file");
    }
    return Status::Ok();
  }
  walkgraph::StatusOr<std::string> Next() {
    if (!reading_ && file_ != nullptr) {
      std::fflush(file_);
      std::rewind(file_);
      reading_ = true;
    }
    uint64_t n = 0;
    if (file_ == nullptr || std::fread(&n, sizeof(n), 1, file_) != 1) {
      return walkgraph::IoError("compare: cannot read back a finished run");
    }
    std::string bytes(n, '\0');
    if (n > 0 && std::fread(bytes.data(), 1, n, file_) != n) {
      return walkgraph::IoError("compare: cannot read back a finished run");
    }
    return bytes;
  }

 private:
  std::FILE* file_;
  bool reading_ = false;
};

// Collective: the rounds (see above). Rank 0 gets the merged comparison in `out`; a failure on
// rank 0 is kept while the rounds go on (every rank takes part in each).
Status MergeSharedRuns(const walkgraph_cli::MpiJob& job, const PreparedCompare& p, RunSpill* spill,
                       std::optional<walkgraph::Comparison>* out) {
  const int ranks = job.size(), runs = p.mc.runs;
  std::optional<walkgraph::ScenarioRunMerger> merger;
  if (job.rank() == 0) merger.emplace(p.scenario, p.mc);
  Status status;
  for (int first = 0; first < runs; first += ranks) {
    std::string mine;  // 'R' + the run's bytes, or 'E' + why there are none
    if (first + job.rank() < runs) {
      auto bytes = spill->Next();
      mine = bytes.ok() ? "R" + *bytes : "E" + bytes.status().message();
    }
    auto gathered = job.Gather(mine);
    if (!gathered.ok()) return gathered.status();  // the same on every rank
    for (int r = 0; job.rank() == 0 && r < ranks && first + r < runs && status.ok(); ++r) {
      const std::string& g = (*gathered)[r];
      const std::string origin = "rank " + std::to_string(r) + ", run " + std::to_string(first + r);
      if (g.empty() || g[0] != 'R') {
        status = walkgraph::IoError(origin + ": " + (g.empty() ? "no bytes" : g.substr(1)));
      } else {
        status = merger->Add(g.substr(1), origin);
      }
    }
  }
  if (job.rank() != 0 || !status.ok()) return status;
  auto merged = merger->Finish();
  if (!merged.ok()) return merged.status();
  *out = std::move(merged).value();
  return Status::Ok();
}

int RunSharedCompare(const CompareArgs& args, const Status& prepared, PreparedCompare* p,
                     const walkgraph_cli::MpiJob& job) {
  Status s = prepared;
  if (s.ok() && args.scenario.empty()) {
    s = walkgraph::InvalidArgument(
        "compare: under MPI give --scenario NAME (a recorded walk "
        "runs on rank 0 alone: start it without mpirun)");
  }
  s = AgreeAcrossRanks(job, s);
  RunSpill spill;
  if (s.ok()) {
    if (job.rank() == 0) {
      p->mc.progress =
          MakeProgress("compare: rank 0 of " + std::to_string(job.size()) + ": ", "of its runs");
    }
    s = walkgraph::CompareScenarioShare(
        args.scenario, p->scenario, p->options, p->mc, {job.rank(), job.size()},
        [&spill](int, std::string bytes) { return spill.Append(bytes); });
    s = AgreeAcrossRanks(job, s);
  }
  std::optional<walkgraph::Comparison> comparison;
  if (s.ok()) s = MergeSharedRuns(job, *p, &spill, &comparison);
  int rc = 0;
  if (job.rank() == 0) rc = s.ok() ? WriteCompare(args, *comparison) : Fail(s);
  return job.Broadcast(rc);
}

int RunCompare(const CompareArgs& args) {
  PreparedCompare p;
  const Status prepared = PrepareCompare(args, g_job->rank() == 0, &p);
  if (g_ranks_share) return RunSharedCompare(args, prepared, &p, *g_job);
  if (!prepared.ok()) return Fail(prepared);
  walkgraph::StatusOr<walkgraph::Comparison> comparison =
      walkgraph::FailedPrecondition("compare: nothing to compare");
  if (!args.walk_dir.empty()) {
    auto walk = ReadWalk(args.walk_dir);
    if (!walk.ok()) return Fail(walk.status());
    p.options.progress = MakeProgress("compare: ", "estimators");
    comparison = walkgraph::CompareOnWalk(*walk, p.options);
  } else {
    p.mc.progress = MakeProgress("compare: ", "runs");
    comparison = walkgraph::CompareScenario(args.scenario, p.scenario, p.options, p.mc);
  }
  if (!comparison.ok()) return Fail(comparison.status());
  return WriteCompare(args, *comparison);
}

int RunPcrb(const std::string& scenario, const std::string& scenario_config,
            const std::string& config_path, int runs, uint64_t seed, int threads) {
  YAML::Node overrides;
  if (!scenario_config.empty()) {
    auto node = walkgraph::LoadYamlFile(scenario_config);
    if (!node.ok()) return Fail(node.status());
    overrides = *node;
  }
  auto config = LoadConfig(config_path);
  if (!config.ok()) return Fail(config.status());
  auto options =
      walkgraph::PcrbOptionsFromYaml(*config, config_path.empty() ? "pcrb" : config_path);
  if (!options.ok()) return Fail(options.status());
  auto bound = walkgraph::ScenarioPcrb(scenario, overrides, runs, seed, threads, *options);
  if (!bound.ok()) {
    const std::string where = scenario_config.empty() ? "" : scenario_config + ": ";
    return Fail(Status(bound.status().code(), where + bound.status().message()));
  }
  std::printf("scenario %s, runs %d, seed %llu: PCRB of the position RMSE\n", scenario.c_str(),
              runs, static_cast<unsigned long long>(seed));
  std::printf("  filter (Tichavsky recursion)  %.4f m\n", bound->filter_rmse_m);
  std::printf("  smoother (full-walk info)     %.4f m\n", bound->smoother_rmse_m);
  std::printf("  %zu states, %.1f readings per run\n", bound->t_s.size(), bound->readings);
  return 0;
}

// walkgraph study: this process's part of the study (the whole study when it runs alone; part
// rank of size under MPI; part i of n with --shard), gathered on rank 0, which merges the parts
// with the library's MergeStudyParts and writes the output. Single process, MPI and --shard go
// through the same bytes (SerializeStudyPart), so the outputs are the same.
struct StudyArgs {
  std::string manifest, out, shard;
  int threads = 1;
};

// What a process sends to rank 0: 'P' + its part's bytes, 'E' + code + ' ' + message (it
// failed), or 'A' (it stopped because another process failed).
constexpr char kOtherFailed[] = "stopped: another process of the study failed";

std::string RunOwnPart(const StudyArgs& a, const walkgraph_cli::MpiJob& job,
                       const walkgraph::StudyShard& shard, const std::function<int()>& claim_cell,
                       std::optional<walkgraph::StudyManifest>* manifest_out) {
  Status local;
  auto manifest = walkgraph::ReadStudyManifest(a.manifest);
  if (!manifest.ok()) local = manifest.status();
  if (local.ok() && job.rank() == 0) {
    std::vector<std::string> inputs = {a.manifest};
    for (const auto& sweep : manifest->sweeps) inputs.push_back(sweep.walk_dir);
    local = Preflight(a.out, walkgraph::OutputKind::kFolder, inputs);
  }
  bool agreed = false;  // every process takes part in the agreement exactly once
  walkgraph::StatusOr<walkgraph::StudyPart> part = walkgraph::InternalError("the part did not run");
  if (!local.ok()) part = local;
  if (local.ok()) {
    walkgraph::StudyOptions options;
    options.threads = a.threads;
    options.claim_cell = claim_cell;
    options.validated = [&](const Status& v) {
      agreed = true;
      return job.AllOk(v.ok()) ? Status::Ok() : walkgraph::Cancelled(kOtherFailed);
    };
    if (job.rank() == 0) {
      options.progress = MakeProgress(
          job.size() > 1 ? "study: rank 0 of " + std::to_string(job.size()) + ": " : "study: ",
          "cells");
    }
    part = walkgraph::RunStudyPart(*manifest, shard, options);
    if (job.rank() == 0 && job.size() > 1 && ::isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
    *manifest_out = std::move(manifest).value();
  }
  if (!agreed) job.AllOk(false);
  if (part.ok()) return "P" + walkgraph::SerializeStudyPart(*part);
  if (part.status().message() == kOtherFailed) return "A";
  return "E" + std::to_string(static_cast<int>(part.status().code())) + " " +
         part.status().message();
}

// Rank 0: the processes' parts (in rank order) merged and written, or the first failure.
int WriteGatheredStudy(const StudyArgs& a, const std::vector<std::string>& gathered,
                       const walkgraph::StudyManifest* manifest) {
  for (const std::string& g : gathered) {
    if (g.empty() || g[0] != 'E') continue;
    const size_t space = g.find(' ');
    const int code = std::atoi(g.substr(1, space).c_str());
    return Fail(Status(static_cast<walkgraph::StatusCode>(code), g.substr(space + 1)));
  }
  std::vector<walkgraph::StudyPart> parts;
  for (size_t r = 0; r < gathered.size(); ++r) {
    const std::string& g = gathered[r];
    if (g.empty() || g[0] != 'P' || manifest == nullptr) {
      return Fail(walkgraph::InternalError("rank " + std::to_string(r) + " sent no part"));
    }
    auto part = walkgraph::ParseStudyPart(g.substr(1), "rank " + std::to_string(r));
    if (!part.ok()) return Fail(part.status());
    parts.push_back(std::move(part).value());
  }
  if (!a.shard.empty()) {
    const Status s = walkgraph::WriteStudyPart(parts.front(), a.out, g_output);
    if (!s.ok()) return Fail(s);
    std::cout << "wrote part " << a.shard << " to " << a.out << "/" << walkgraph::kStudyPartFile
              << " (walkgraph study merge PARTS... --out DIR combines the parts)\n";
    return 0;
  }
  auto result = walkgraph::MergeStudyParts(*manifest, parts);
  if (!result.ok()) return Fail(result.status());
  std::cout << walkgraph::FormatStudyTable(*result);
  const Status s = walkgraph::WriteStudy(*result, a.out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << a.out << "/{study.csv,study.html,timing.csv}\n";
  return 0;
}

int RunStudy(const StudyArgs& a, const walkgraph_cli::MpiJob& job) {
  walkgraph::StudyShard shard{job.rank(), job.size()};
  if (!a.shard.empty()) {
    if (job.size() > 1) {
      if (job.rank() != 0) return 1;
      return Fail(
          walkgraph::InvalidArgument("study: --shard is for runs without MPI; under "
                                     "mpirun the ranks share the cells themselves"));
    }
    auto parsed = walkgraph::ParseStudyShard(a.shard);
    if (!parsed.ok()) return Fail(parsed.status());
    shard = *parsed;
  }
  std::optional<walkgraph::StudyManifest> manifest;
  std::string mine;
  if (job.size() > 1) {
    // The ranks claim cells from one counter as they finish theirs (the cost model
    // runs × estimators cannot know which cells are slow); the outputs do not depend on who ran
    // which cell.
    walkgraph_cli::SharedCounter counter(job);
    mine = RunOwnPart(
        a, job, shard, [&counter] { return counter.FetchAdd(); }, &manifest);
  } else {
    mine = RunOwnPart(a, job, shard, nullptr, &manifest);
  }
  auto gathered = job.Gather(mine);
  int rc = 0;
  if (job.rank() == 0) {
    rc = gathered.ok() ? WriteGatheredStudy(a, *gathered, manifest ? &*manifest : nullptr)
                       : Fail(gathered.status());
  }
  return job.Broadcast(rc);
}

// walkgraph study merge PARTS... --out DIR
int RunStudyMerge(const std::vector<std::string>& parts, const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, parts); !s.ok()) return Fail(s);
  auto result = walkgraph::MergeStudyPartFiles(parts);
  if (!result.ok()) return Fail(result.status());
  std::cout << walkgraph::FormatStudyTable(*result);
  const Status s = walkgraph::WriteStudy(*result, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << "/{study.csv,study.html,timing.csv}\n";
  return 0;
}

int RunSimulate(const std::string& scenario, uint64_t seed, const std::string& config_path,
                const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, {config_path}); !s.ok()) {
    return Fail(s);
  }
  auto config = LoadConfig(config_path);
  if (!config.ok()) return Fail(config.status());
  auto walk = walkgraph::SimulateScenario(scenario, seed, *config);
  if (!walk.ok()) {
    const bool about_config = walk.status().code() == walkgraph::StatusCode::kInvalidArgument;
    return Fail(about_config ? InConfig(config_path, walk.status()) : walk.status());
  }
  const Status s = walkgraph::WriteWalk(*walk, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << " (" << walk->imu.size() << " IMU, " << walk->rss.size()
            << " RSS, " << walk->ranges.size() << " range, " << walk->odometry.size()
            << " odometry samples; " << walk->EndTime() - walk->StartTime() << " s)\n";
  return 0;
}

int RunStanceSearch(const std::string& walk_dir, const std::string& detector,
                    const std::string& config_path, const std::vector<double>& thresholds) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  auto config = LoadConfig(config_path);
  if (!config.ok()) return Fail(config.status());
  auto options = walkgraph::StanceOptionsFromYaml(*config);
  if (!options.ok()) return Fail(InConfig(config_path, options.status()));
  auto type = walkgraph::StanceDetectorFromString(detector);
  if (!type.ok()) return Fail(type.status());
  options->detector = *type;
  auto scores = walkgraph::StanceThresholdSearch(*walk, *options, thresholds);
  if (!scores.ok()) return Fail(scores.status());
  std::printf("# %s, detector %s, window %d: stance precision/recall vs stance_truth\n",
              walk_dir.c_str(), detector.c_str(), options->window);
  std::printf("%12s %9s %9s %9s %9s %9s %9s\n", "threshold", "precision", "recall", "F1", "TP",
              "FP", "FN");
  for (const auto& s : *scores) {
    const double p = s.precision(), r = s.recall();
    const double f1 = p + r > 0 ? 2 * p * r / (p + r) : 0.0;
    std::printf("%12.5g %9.4f %9.4f %9.4f %9ld %9ld %9ld\n", s.threshold, p, r, f1, s.true_positive,
                s.false_positive, s.false_negative);
  }
  return 0;
}

void AddForce(CLI::App* command) {
  command->add_flag("--force", g_output.force,
                    "replace an existing --out folder that walkgraph did not write (one without "
                    "its .walkgraph-output marker); the input, '.', its ancestors and the home "
                    "folder are never replaced");
}

void AddThreads(CLI::App* command, int* threads, const std::string& help) {
  command->add_option("--threads", *threads, help)->check(CLI::Range(0, walkgraph::kMaxThreads));
}

// An option's default as the YAML reader holds it.
std::string DefaultText(const walkgraph::OptionDefault& d) {
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          return v ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::string>) {
          return "'" + v + "'";
        } else {
          std::ostringstream s;
          s << v;
          return s.str();
        }
      },
      d.value);
}

// walkgraph list ID: the estimator's description and every option it accepts with its default
// (the keys the YAML reader records, so the list cannot drift from what a config may set).
int RunListEstimator(const std::string& id) {
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  const walkgraph::EstimatorInfo* info = registry.Find(id);
  if (info == nullptr) return Fail(registry.Create(id).status());
  auto defaults = registry.OptionDefaults(id);
  if (!defaults.ok()) return Fail(defaults.status());
  std::cout << id << "  — " << info->description << "\n";
  if (defaults->empty()) {
    std::cout << "options: none\n";
    return 0;
  }
  std::cout << "options (YAML keys of --config): default, unit (from the key's suffix) or the "
               "values a string option allows, what it does:\n";
  auto extra_of = [](const walkgraph::OptionDefault& d) {
    std::string allowed;
    for (const std::string& a : d.allowed) allowed += (allowed.empty() ? "" : "|") + a;
    const std::string unit = walkgraph::OptionUnit(d.key);
    return !unit.empty() ? unit : allowed.empty() ? "" : "one of " + allowed;
  };
  size_t width = 0, value_width = 0, extra_width = 0;
  for (const auto& d : *defaults) {
    width = std::max(width, d.key.size());
    value_width = std::max(value_width, DefaultText(d).size());
    if (extra_of(d).size() <= 12) extra_width = std::max(extra_width, extra_of(d).size());
  }
  auto pad = [](const std::string& s, size_t w) {
    return s + std::string(std::max(w, s.size()) - s.size() + 2, ' ');
  };
  for (const auto& d : *defaults) {
    std::string line = "  " + pad(d.key, width) + pad(DefaultText(d), value_width) +
                       pad(extra_of(d), extra_width) + d.doc;
    while (!line.empty() && line.back() == ' ') line.pop_back();
    std::cout << line << "\n";
  }
  return 0;
}

int RunList(const std::string& id) {
  if (!id.empty()) return RunListEstimator(id);
  std::cout
      << "estimators (walkgraph list ID: its options with defaults, units and allowed values):\n";
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const std::string& e : registry.Ids()) {
    std::cout << "  " << e << "  — " << registry.Find(e)->description << "\n";
  }
  std::cout << "formats (walkgraph convert FORMAT SRC...):\n";
  for (const auto& c : walkgraph::Converters()) {
    std::cout << "  " << c.format << "  — " << c.description << "\n";
  }
  std::cout << "scenarios (walkgraph simulate --scenario NAME):\n";
  for (const auto& sc : walkgraph::Scenarios()) {
    std::cout << "  " << sc.name << "  — " << sc.description << "\n";
  }
  return 0;
}

// What the command line fills in: one field per option of any command (only one command runs).
struct CliArgs {
  std::string walk_dir, out, id, config_path, format, ipin_out, scenario, list_id;
  std::vector<std::string> sources;
  walkgraph::ConvertOptions convert_options;
  bool fit_floors = false;
  CompareArgs compare;
  PcrbArgs pcrb;
  StudyArgs study;
  std::string compare_seed = "1", pcrb_seed = "1", simulate_seed;
  std::vector<std::string> merge_parts;
  std::string merge_out;
  std::string detector = "glrt";
  std::vector<double> thresholds;
  int rc = 0;
};

void AddWalkCommands(CLI::App* app, CliArgs* a) {
  CLI::App* validate = app->add_subcommand("validate", "check a walk directory strictly");
  validate->add_option("WALK", a->walk_dir, "walk directory")->required();
  validate->callback([a] { a->rc = RunValidate(a->walk_dir); });

  CLI::App* convert = app->add_subcommand("convert", "convert a recording to a walk directory");
  convert->add_option("FORMAT", a->format, "source format (see walkgraph list)")->required();
  convert->add_option("SRC", a->sources, "source files or directories")->required();
  convert->add_option("--out", a->out, "walk directory to write")->required();
  AddForce(convert);
  convert->add_flag("--known-start", a->convert_options.known_start,
                    "ipin: start at the first POSI landmark, its position given as initial_pose "
                    "(heading unknown), as IPIN's scoring trials provide it; the log before it "
                    "is dropped");
  convert->add_option("--known-start-sigma", a->convert_options.known_start_sigma_m,
                      "ipin: sigma of that start position, m (default 0.5)");
  convert->add_flag("--strict", a->convert_options.strict,
                    "refuse a source holding a physically impossible reading (default: drop it, "
                    "count it in walk.yaml extra convert.<stream>_invalid_dropped, warn with its "
                    "file:line)");
  convert->callback([a] { a->rc = RunConvert(a->format, a->sources, a->convert_options, a->out); });

  CLI::App* fit = app->add_subcommand(
      "fit-path-loss", "fit A, eta, sigma of the log-distance path loss to a walk's RSS vs truth");
  fit->add_option("WALK", a->walk_dir, "walk directory")->required();
  fit->add_flag("--floors", a->fit_floors,
                "multi-floor walk: anchors at their floors' heights, and the floor loss per floor "
                "crossed (floor_loss_db) fitted with A and eta");
  fit->callback([a] { a->rc = RunFitPathLoss(a->walk_dir, a->fit_floors); });

  CLI::App* smooth = app->add_subcommand("smooth", "run one estimator, write a TUM trajectory");
  smooth->add_option("WALK", a->walk_dir, "walk directory")->required();
  smooth->add_option("--estimator", a->id, "estimator id (see walkgraph list)")->required();
  smooth->add_option("--config", a->config_path, "YAML file with the estimator's options");
  smooth->add_option("--out", a->out, "output trajectory (TUM format)")->required();
  smooth->add_option("--ipin-out", a->ipin_out,
                     "also write IPIN's submission (lon,lat,floor at 2 Hz from t = 0; walks from "
                     "convert ipin)");
  smooth->callback(
      [a] { a->rc = RunSmooth(a->walk_dir, a->id, a->config_path, a->out, a->ipin_out); });
}

void AddCompareCommand(CLI::App* app, CliArgs* a) {
  CompareArgs& c = a->compare;
  CLI::App* compare = app->add_subcommand(
      "compare", "run estimators side by side on a walk, or Monte Carlo on a scenario");
  compare->add_option("WALK", c.walk_dir, "walk directory");
  compare->add_option("--scenario", c.scenario, "simulated scenario (instead of WALK)");
  compare->add_option("--scenario-config", c.scenario_config_path,
                      "YAML file with scenario overrides, e.g. {laps: 2, eta: 3.0}");
  compare->add_option("--runs", c.runs, "Monte Carlo runs of the scenario")
      ->check(CLI::PositiveNumber);
  compare->add_option("--seed", a->compare_seed,
                      "base seed S (run i uses a seed derived from S, i; default 1)");
  AddThreads(compare, &c.threads, "worker threads (0 = all cores)");
  compare->add_option(
      "--estimators", c.ids,
      "comma-separated ids, e.g. \"fg-batch, tarrio-kf\" (default: all applicable)");
  compare->add_option("--config", c.config_path, "YAML file: {estimator id: {option: value}}");
  compare->add_flag("--align-se2", c.align_se2,
                    "align each estimate to the truth by a best-fit rotation + translation "
                    "(for dead-reckoning-only walks)");
  compare
      ->add_option("--score-from", c.score_from_s,
                   "score only truth from S seconds after its first sample on (a filter's "
                   "start-up left out; default 0: the whole walk)")
      ->check(CLI::NonNegativeNumber);
  compare->add_flag("--keep-diverged", c.keep_diverged,
                    "score diverged estimates (and Monte Carlo runs) like the others; they are "
                    "still flagged (default: shown as diverged, left out of the figures)");
  compare->add_option("--out", c.out, "report folder")->required();
  AddForce(compare);
  compare->callback([a] {
    const std::string e = ParseSeed(a->compare_seed, &a->compare.seed);
    a->rc = e.empty() ? RunCompare(a->compare) : Fail(walkgraph::InvalidArgument(e));
  });
}

void AddScenarioCommands(CLI::App* app, CliArgs* a) {
  CLI::App* simulate = app->add_subcommand("simulate", "simulate a paper's scenario as a walk");
  simulate->add_option("--scenario", a->scenario, "scenario name (see walkgraph list)")->required();
  simulate->add_option("--seed", a->simulate_seed, "random seed (same seed, same walk)")
      ->required();
  simulate->add_option("--config", a->config_path, "YAML file with scenario overrides");
  simulate->add_option("--out", a->out, "walk directory to write")->required();
  AddForce(simulate);
  simulate->callback([a] {
    uint64_t seed = 0;
    const std::string e = ParseSeed(a->simulate_seed, &seed);
    a->rc = e.empty() ? RunSimulate(a->scenario, seed, a->config_path, a->out)
                      : Fail(walkgraph::InvalidArgument(e));
  });

  PcrbArgs& p = a->pcrb;
  CLI::App* pcrb = app->add_subcommand(
      "pcrb", "posterior Cramer-Rao bound of a simulated scenario's position RMSE");
  pcrb->add_option("--scenario", p.scenario, "scenario name (see walkgraph list)")->required();
  pcrb->add_option("--scenario-config", p.scenario_config, "YAML file with scenario overrides");
  pcrb->add_option("--config", p.config, "YAML file with PCRB options (see pcrb.h)");
  pcrb->add_option("--runs", p.runs, "Monte Carlo runs")->check(CLI::PositiveNumber);
  pcrb->add_option("--seed", a->pcrb_seed, "base seed S (as compare; default 1)");
  AddThreads(pcrb, &p.threads, "worker threads (0 = all cores)");
  pcrb->callback([a] {
    PcrbArgs& q = a->pcrb;
    const std::string e = ParseSeed(a->pcrb_seed, &q.seed);
    a->rc = e.empty() ? RunPcrb(q.scenario, q.scenario_config, q.config, q.runs, q.seed, q.threads)
                      : Fail(walkgraph::InvalidArgument(e));
  });
}

void AddStudyCommand(CLI::App* app, CliArgs* a) {
  StudyArgs& s = a->study;
  CLI::App* study = app->add_subcommand(
      "study", "parameter sweeps over walks/scenarios and estimators from a manifest");
  study->add_option("MANIFEST", s.manifest, "study manifest (YAML, see study.h)");
  AddThreads(study, &s.threads, "worker threads per cell (0 = all cores)");
  study->add_option("--out", s.out,
                    "output folder (study.csv, study.html; with --shard: the part)");
  study->add_option("--shard", s.shard,
                    "i/n: run only part i (0-based) of n and write it for `study merge` (clusters "
                    "without MPI, e.g. Slurm job arrays; docs/studies-on-clusters.md)");
  AddForce(study);
  CLI::App* merge = study->add_subcommand(
      "merge", "combine the parts written by study --shard i/n into the study's output");
  merge->add_option("PARTS", a->merge_parts, "part folders (or their study.part files)")
      ->required();
  merge->add_option("--out", a->merge_out, "output folder (study.csv, study.html)")->required();
  AddForce(merge);
  merge->callback([a] { a->rc = RunStudyMerge(a->merge_parts, a->merge_out); });
  study->callback([a, study, merge] {
    if (study->got_subcommand(merge)) return;
    if (a->study.manifest.empty() || a->study.out.empty()) {
      a->rc =
          Fail(walkgraph::InvalidArgument("study: give MANIFEST and --out DIR (or: study merge)"));
      return;
    }
    a->rc = RunStudy(a->study, *g_job);
  });
}

void AddToolCommands(CLI::App* app, CliArgs* a) {
  CLI::App* stance = app->add_subcommand(
      "stance-search", "stance detector precision/recall per threshold vs labelled stance");
  stance->add_option("WALK", a->walk_dir, "walk directory with stance_truth.csv")->required();
  stance->add_option("--detector", a->detector, "glrt|mv|mag|are|multi-condition");
  stance->add_option("--config", a->config_path, "YAML file with stance options");
  stance
      ->add_option("--thresholds", a->thresholds,
                   "comma-separated thresholds (default: 40 log-spaced over the statistic)")
      ->delimiter(',');
  stance->callback(
      [a] { a->rc = RunStanceSearch(a->walk_dir, a->detector, a->config_path, a->thresholds); });

  CLI::App* list = app->add_subcommand("list", "list estimators, converter formats and scenarios");
  list->add_option("ID", a->list_id, "an estimator id: print its options with their defaults");
  list->callback([a] { a->rc = RunList(a->list_id); });
}

int Main(int argc, char** argv) {
  walkgraph::InitLogging(argv[0]);
  if (g_job->size() > 1 && !g_ranks_share) {
    if (g_job->rank() != 0) return 0;
    std::cerr << "walkgraph: warning: under MPI only `study` and `compare --scenario` share "
                 "their work among the ranks; this command runs on rank 0 alone\n";
  }
  g_output.command = CommandLine(argc, argv);
  CLI::App app{
      "walkgraph: factor-graph smoothing and Kalman-filter comparison for pedestrian "
      "navigation walks"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("walkgraph ") + WALKGRAPH_VERSION);
  int verbosity = 0;
  app.add_option("-v,--verbosity", verbosity, "library diagnostics level (0 = quiet)");
  CliArgs args;
  AddWalkCommands(&app, &args);
  AddCompareCommand(&app, &args);
  AddScenarioCommands(&app, &args);
  AddStudyCommand(&app, &args);
  AddToolCommands(&app, &args);

  app.parse_complete_callback([&] { walkgraph::InitLogging(argv[0], verbosity); });
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string what = e.what();
    if (what.size() > 300) what = what.substr(0, 300) + "...";
    std::cerr << "walkgraph: " << what << "\n(walkgraph --help, or walkgraph COMMAND --help)\n";
    return 1;
  }
  return Finish(args.rc);
}

// A run whose standard output could not be written (a full disk, /dev/full, a closed pipe's
// EPIPE) failed, even when its files were written: the final flush's errors count.
int CheckStdout(int rc) {
  std::cout.flush();
  const bool stream_bad = !std::cout.good() || std::ferror(stdout) != 0;
  errno = 0;
  const bool flush_failed = std::fflush(stdout) != 0;
  const int e = errno;
  if (!stream_bad && !flush_failed) return rc;
  std::fprintf(
      stderr, "walkgraph: cannot write the standard output: %s\n",
      flush_failed && e != 0 ? std::strerror(e) : "a write failed (a full disk, or a closed pipe)");
  return rc == 0 ? 1 : rc;
}

}  // namespace

int main(int argc, char** argv) {
  walkgraph_cli::MpiJob job(&argc, &argv);
  g_job = &job;
  g_ranks_share = job.size() > 1 && IsSharedRun(argc, argv);
  InstallSignalHandlers();
  std::set_terminate(OnTerminate);
  google::InstallFailureFunction(&OnCheckFailure);
  try {
    return CheckStdout(Main(argc, argv));
  } catch (const std::bad_alloc&) {
    std::cerr << "walkgraph: out of memory; no output was written\n";
  } catch (const std::exception& e) {
    std::cerr << "walkgraph: internal error: " << e.what() << "; no output was written\n";
  } catch (...) {
    std::cerr << "walkgraph: internal error: unexpected exception; no output was written\n";
  }
  return 1;
}
