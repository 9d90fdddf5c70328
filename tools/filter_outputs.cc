// Regression dump of the papers' filters (issue 24): runs every filter estimator (every id not
// starting with "fg-") on walk directories and on every simulated scenario (seed 1, defaults) and
// writes each trajectory as CSV with full precision; --compare reports max |Δposition| per file.
//
//   filter_outputs dump OUT_DIR [WALK_DIR...]      (scenarios always included)
//   filter_outputs compare BEFORE_DIR AFTER_DIR     (exit 1 on a missing file or Δ > 1e-9 m)
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "util/text.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/logging.h"
#include "walkgraph/simulate.h"

namespace {

namespace fs = std::filesystem;

void Write(const walkgraph::EstimateResult& r, const fs::path& path) {
  std::ofstream o(path);
  char buf[256];
  for (const walkgraph::TrajectoryPoint& p : r.trajectory.points) {
    std::snprintf(buf, sizeof(buf), "%.17g,%.17g,%.17g,%.17g,%.17g\n", p.t_s, p.position_m.x(),
                  p.position_m.y(), p.position_m.z(), p.heading_rad);
    o << buf;
  }
}

int Dump(const fs::path& out, const std::vector<std::string>& walk_dirs) {
  fs::create_directories(out);
  std::vector<std::pair<std::string, walkgraph::Walk>> walks;
  for (const std::string& dir : walk_dirs) {
    auto w = walkgraph::ReadWalk(dir);
    if (!w.ok()) {
      std::cerr << dir << ": " << w.status().message() << "\n";
      return 1;
    }
    walks.emplace_back(fs::path(dir).filename().string(), std::move(*w));
  }
  for (const walkgraph::ScenarioInfo& s : walkgraph::Scenarios()) {
    auto w = walkgraph::SimulateScenario(s.name, 1);
    if (!w.ok()) {
      std::cerr << s.name << ": " << w.status().message() << "\n";
      return 1;
    }
    walks.emplace_back("sim-" + s.name, std::move(*w));
  }
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const std::string& id : registry.Ids()) {
    if (id.rfind("fg-", 0) == 0) continue;
    auto est = registry.Create(id);
    if (!est.ok()) {
      std::cerr << id << ": " << est.status().message() << "\n";
      return 1;
    }
    for (const auto& [name, walk] : walks) {
      if (!(*est)->CheckApplicable(walk).ok()) continue;
      auto r = (*est)->Run(walk);
      const fs::path path = out / (id + "__" + name + ".csv");
      if (!r.ok()) {
        std::ofstream(path.string() + ".error") << r.status().message() << "\n";
        continue;
      }
      Write(*r, path);
    }
    std::cerr << id << " done\n";
  }
  return 0;
}

std::vector<std::vector<double>> Read(const fs::path& path) {
  std::vector<std::vector<double>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<double> row;
    for (const std::string& field : walkgraph::internal::Split(line, ',')) {
      row.push_back(std::stod(field));
    }
    rows.push_back(row);
  }
  return rows;
}

int Compare(const fs::path& before, const fs::path& after) {
  int bad = 0;
  double worst = 0.0;
  for (const auto& e : fs::directory_iterator(before)) {
    const fs::path other = after / e.path().filename();
    if (!fs::exists(other)) {
      std::cout << "MISSING " << e.path().filename().string() << "\n";
      ++bad;
      continue;
    }
    if (e.path().extension() != ".csv") continue;
    const auto a = Read(e.path()), b = Read(other);
    if (a.size() != b.size()) {
      std::cout << "ROWS " << e.path().filename().string() << " " << a.size() << " vs " << b.size()
                << "\n";
      ++bad;
      continue;
    }
    double d = 0.0, dt = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
      dt = std::max(dt, std::fabs(a[i][0] - b[i][0]));
      d = std::max(d,
                   std::hypot(std::hypot(a[i][1] - b[i][1], a[i][2] - b[i][2]), a[i][3] - b[i][3]));
    }
    worst = std::max(worst, d);
    if (d > 1e-9 || dt > 1e-9 || d > 0) {
      std::cout << (d > 1e-9 || dt > 1e-9 ? "DIFF " : "tiny ") << e.path().filename().string()
                << " max|dp|=" << d << " max|dt|=" << dt << "\n";
    }
    if (d > 1e-9 || dt > 1e-9) ++bad;
  }
  for (const auto& e : fs::directory_iterator(after)) {
    if (!fs::exists(before / e.path().filename())) {
      std::cout << "NEW " << e.path().filename().string() << "\n";
      ++bad;
    }
  }
  std::cout << "max |dposition| over all files: " << worst << " m; " << bad << " problem(s)\n";
  return bad == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  walkgraph::InitLogging(argv[0]);
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() >= 2 && args[0] == "dump") {
    return Dump(args[1], std::vector<std::string>(args.begin() + 2, args.end()));
  }
  if (args.size() == 3 && args[0] == "compare") return Compare(args[1], args[2]);
  std::cerr << "usage: filter_outputs dump OUT_DIR [WALK_DIR...] | compare BEFORE AFTER\n";
  return 2;
}
