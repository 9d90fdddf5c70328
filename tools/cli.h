// The walkgraph command's parts (tools/walkgraph.cc parses the command line and calls them):
// what every command shares (cli_common.cc: errors, inputs, progress, options), and the
// commands by room: cli_walk_commands.cc (validate, convert, fit-path-loss, smooth, simulate,
// stance-search, list), cli_compare.cc (compare, on one process or the ranks of an MPI job;
// pcrb), cli_study.cc (study, study merge).
#ifndef WALKGRAPH_TOOLS_CLI_H_
#define WALKGRAPH_TOOLS_CLI_H_

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
#include "walkgraph/survey.h"

#include "mpi_job.h"

namespace walkgraph_cli {

using walkgraph::Status;

// ------------------------------------------------------------------ shared (cli_common.cc)
// What every output of this run is written with: --force, the command line for the marker, and
// the run's inputs (set by each command).
extern walkgraph::OutputOptions g_output;

// The processes of this run (mpi_job.h): one, or the ranks of an MPI job.
extern const walkgraph_cli::MpiJob* g_job;

// Whether the ranks of an MPI job share this run's work (set by main): the command line runs a
// study, or a scenario's Monte Carlo comparison (compare --scenario NAME), and there is more
// than one rank. Other commands run on rank 0 alone.
extern bool g_ranks_share;

// --radio-map MAP (compare, smooth): the folder `walkgraph survey` wrote; "" none. ReadWalk
// applies its anchors.csv to the walk (survey.h ApplyRadioMap).
extern std::string g_radio_map;
int Fail(const Status& s);

// Reads a walk and prints what it holds that is unusual but accepted (io.h
// PlausibilityWarnings: e.g. holes in the IMU stream, which the estimators bridge instead of
// integrating across); compare also counts them in results.json.
walkgraph::StatusOr<walkgraph::Walk> ReadWalk(const std::string& dir);

// An error about a --config file's contents, prefixed with the file's path (the library names the
// estimator and the line, but it does not know the file).
Status InConfig(const std::string& path, const Status& s);

// After a command's outputs are written: a signal that came during the write (too late to keep
// the old output) still ends the run as interrupted.
int Finish(int rc);

// A seed: a decimal integer in [0, 2^64 - 1] (CLI11 would wrap "-1" to 2^64 - 1).
std::string ParseSeed(const std::string& text, uint64_t* seed);

// --estimators "a, b,c": ids without empty entries; spaces around an id are ignored.
walkgraph::StatusOr<std::vector<std::string>> SplitIds(const std::string& text);

// Reads --config FILE.yaml: either the options of one estimator, or (for compare) a map from
// estimator id to its options.
walkgraph::StatusOr<YAML::Node> LoadConfig(const std::string& path);

// Fails at once when --out would be refused at the end (see walkgraph/output.h).
Status Preflight(const std::string& out, walkgraph::OutputKind kind,
                 std::vector<std::string> inputs);

// compare --config: a map from estimator id to that estimator's options.
Status ConfigsById(const YAML::Node& config, const std::string& path,
                   std::map<std::string, walkgraph::Config>* out);

// "42 s", "3 min 07 s", "2 h 05 min", "12.5 days".
std::string Duration(double s);

// Seconds between two progress lines in a log: 10, or WALKGRAPH_PROGRESS_INTERVAL_S (a
// number >= 0; for tests, which set 0 to see every line without a slow run).
double ProgressInterval();

// "3" or "2.4" (a fraction of the units: an estimator part-way through its walk).
std::string Count(double done);

void AddForce(CLI::App* command);

void AddThreads(CLI::App* command, int* threads, const std::string& help);

// Progress of a long run on stderr with a time estimate (elapsed / done × the rest): on a
// terminal a bar redrawn in place (at most 10 times a second); else (a batch job's log) a plain
// line every ProgressInterval() s, the first after one interval (a short run prints nothing) and
// one at the end if any came before. `done` may be fractional (compare on one walk: estimators
// done plus the running one's fraction). The calls may come from several threads.
std::function<void(double, int)> MakeProgress(const std::string& prefix, const std::string& unit);

// ------------------------------------------------------------------ cli_walk_commands.cc
int RunValidate(const std::string& walk_dir);

int RunConvert(const std::string& format, const std::vector<std::string>& sources,
               const walkgraph::ConvertOptions& options, const std::string& out);

// Fits RSS = A − 10·η·log10(d/d0) to a walk's RSS readings against its truth (positions
// linearly interpolated between truth samples; readings outside the truth's span are skipped;
// the distance is 3-D when the truth has a height, else horizontal to the anchor's x-y with the
// anchor's height against 0). With `floors` (--floors; truth and anchors with floors): the
// receiver at its truth floor's height, the anchor at Walk::AnchorHeightM, and the floor loss
// per floor crossed fitted with A and η (FitPathLoss) — the model of the step-graph estimators
// when floor_loss_db > 0, not of the planar filters (their A, η come from the plain fit). Prints a
// `radio:` block for walk.yaml (global fit) and the fit per anchor as comments. Meant to calibrate
// one walk's path loss for use on a different walk.
int RunFitPathLoss(const std::string& walk_dir, bool floors);

int RunSmooth(const std::string& walk_dir, const std::string& id, const std::string& config_path,
              const std::string& out, const std::string& ipin_out);

// walkgraph survey: a radio map from walks with truth (survey.h SurveyRadioMap), written as the
// folder `out`: anchors.csv (the map) and survey.csv (per mapped anchor: covariance, walks,
// readings, disagreement).
int RunSurvey(const std::vector<std::string>& walk_dirs, const walkgraph::SurveyOptions& options,
              const std::string& out);
int RunSimulate(const std::string& scenario, uint64_t seed, const std::string& config_path,
                const std::string& out);

int RunStanceSearch(const std::string& walk_dir, const std::string& detector,
                    const std::string& config_path, const std::vector<double>& thresholds);

int RunList(const std::string& id);

// ------------------------------------------------------------------ cli_compare.cc
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

int RunCompare(const CompareArgs& args);

int RunPcrb(const std::string& scenario, const std::string& scenario_config,
            const std::string& config_path, int runs, uint64_t seed, int threads);

// ------------------------------------------------------------------ cli_study.cc
// walkgraph study: this process's part of the study (the whole study when it runs alone; part
// rank of size under MPI; part i of n with --shard), gathered on rank 0, which merges the parts
// with the library's MergeStudyParts and writes the output. Single process, MPI and --shard go
// through the same bytes (SerializeStudyPart), so the outputs are the same.
struct StudyArgs {
  std::string manifest, out, shard;
  int threads = 1;
};

int RunStudy(const StudyArgs& a, const walkgraph_cli::MpiJob& job);

// walkgraph study merge PARTS... --out DIR
int RunStudyMerge(const std::vector<std::string>& parts, const std::string& out);

}  // namespace walkgraph_cli

#endif  // WALKGRAPH_TOOLS_CLI_H_
