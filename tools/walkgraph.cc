// walkgraph: the command-line shell over the library. Parses arguments, calls the library,
// prints. Every failure prints "walkgraph: <message>" on stderr and exits 1; an interrupted
// run (SIGINT, SIGTERM, SIGHUP, SIGQUIT) exits 128 + the signal, its outputs left as they were
// (walkgraph/output.h).
#include "cli.h"

namespace walkgraph_cli {
namespace {

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

// ------------------------------------------------- compare --scenario under MPI
// The ranks share the Monte Carlo runs round robin (run r on rank r % N: deterministic, and
// balanced within one run); each runs its share on its --threads (the library's
// CompareScenarioShare) and keeps each finished run's bytes in a temporary file. Then rank 0
// takes the runs in run order, one round of N runs at a time (run k·N + r from rank r, one
// Gather per round), through the library's ScenarioRunMerger and writes the outputs: the same
// bytes as one process, with memory that does not grow with the runs.

// What the command line fills in: one field per option of any command (only one command runs).
struct CliArgs {
  std::string walk_dir, out, id, config_path, format, ipin_out, scenario, list_id;
  std::vector<std::string> sources;
  walkgraph::ConvertOptions convert_options;
  walkgraph::SurveyOptions survey;
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
  convert->add_flag("--wifi", a->convert_options.ipin_wifi,
                    "ipin: the WIFI readings too, each access point an anchor of unknown position "
                    "(group wifi; only the factor graphs place it)");
  convert
      ->add_option("--wifi-min-readings", a->convert_options.ipin_wifi_min_readings,
                   "ipin: an access point heard fewer times is dropped (default 10)")
      ->check(CLI::PositiveNumber);
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
  smooth->add_option("--radio-map", g_radio_map,
                     "a radio map from walkgraph survey: the walk's unsurveyed anchors it places "
                     "get its positions as priors");
  smooth->callback(
      [a] { a->rc = RunSmooth(a->walk_dir, a->id, a->config_path, a->out, a->ipin_out); });

  CLI::App* survey = app->add_subcommand(
      "survey", "a radio map from walks with truth: their unsurveyed anchors placed (fg-batch)");
  survey->add_option("WALK", a->sources, "walk directories (one building, with truth.csv)")
      ->required();
  survey->add_option("--out", a->out, "radio map folder to write (anchors.csv, survey.csv)")
      ->required();
  survey->add_option("--checkpoint-sigma", a->survey.checkpoint_sigma_m,
                     "1-sigma of a truth sample used as a position factor, m (default 0.5)");
  survey->add_flag("!--no-pool-disagreement", a->survey.pool_disagreement,
                   "each anchor keeps its own walks' covariance, not scaled by the walks' median "
                   "disagreement");
  AddForce(survey);
  survey->callback([a] { a->rc = RunSurvey(a->sources, a->survey, a->out); });
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
  compare->add_option("--radio-map", g_radio_map,
                      "a radio map from walkgraph survey: the walk's unsurveyed anchors it "
                      "places get its positions as priors (the filters use them as positions)");
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
}  // namespace walkgraph_cli

int main(int argc, char** argv) {
  using namespace walkgraph_cli;  // NOLINT(build/namespaces): the command's own parts
  MpiJob job(&argc, &argv);
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
