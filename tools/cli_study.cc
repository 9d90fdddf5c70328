// walkgraph study and study merge.
#include "cli.h"

namespace walkgraph_cli {

namespace {

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

}  // namespace

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

}  // namespace walkgraph_cli
