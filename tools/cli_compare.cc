// walkgraph compare (one process, or the ranks of an MPI job) and pcrb.
#include "cli.h"

namespace walkgraph_cli {

namespace {

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
  if (!g_radio_map.empty() && args.walk_dir.empty()) {
    return walkgraph::InvalidArgument("compare: --radio-map needs WALK (not --scenario)");
  }
  if (preflight) {
    WG_RETURN_IF_ERROR(
        Preflight(args.out, walkgraph::OutputKind::kFolder,
                  {args.walk_dir, args.config_path, args.scenario_config_path, g_radio_map}));
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

}  // namespace

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

}  // namespace walkgraph_cli
