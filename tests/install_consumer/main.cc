// A research program linking the installed walkgraph: reads a walk given on the command line,
// runs an estimator from the registry with options given as YAML text (walkgraph::Config: no
// yaml-cpp needed here) and prints how many poses came back.
#include <iostream>

#include "walkgraph/estimator.h"
#include "walkgraph/io.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  auto walk = walkgraph::ReadWalk(argv[1]);
  if (!walk.ok()) {
    std::cerr << walk.status().message() << "\n";
    return 1;
  }
  auto config = walkgraph::Config::Parse("{}", "odometry-dr options");
  if (!config.ok()) return 1;
  auto est = walkgraph::EstimatorRegistry::Builtin().Create("odometry-dr", *config);
  if (!est.ok()) return 1;
  auto result = (*est)->Run(*walk);
  if (!result.ok()) return 1;
  std::cout << "poses " << result->trajectory.size() << "\n";
  return result->trajectory.size() > 0 ? 0 : 1;
}
