// libFuzzer target for everything walkgraph reads from users' files: the walk format (walk.yaml
// and every CSV stream), --config files (every estimator's options, the PCRB and stance options)
// and study manifests. Built with -DWALKGRAPH_FUZZ=ON under clang; tools/run_fuzz.sh builds the
// seed corpora from tests/data and datasets/ and runs each reader for a bounded time (CI).
//
// The reader is chosen by WALKGRAPH_FUZZ_READER (walk | config | manifest; default walk):
//   walk: the first byte picks one file of a valid walk, the rest replaces it; ReadWalk must
//         return a Status (never crash, hang or trip a sanitizer), and what it accepts the
//         in-memory validator must accept too.
//   config: the input is a YAML file given to every estimator as its options, and as PCRB and
//         stance options.
//   manifest: the input is a study manifest.
//
//   CC=clang CXX=clang++ cmake -S . -B build-fuzz -DWALKGRAPH_FUZZ=ON -DWALKGRAPH_BUILD_TESTS=OFF
//   cmake --build build-fuzz --target fuzz_readers
//   WALKGRAPH_FUZZ_READER=config ./build-fuzz/tools/fuzz_readers -max_total_time=60 CORPUS
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "config/reader.h"
#include "eval/pcrb_yaml.h"
#include "stance/stance_yaml.h"
#include "walkgraph/config.h"
#include "walkgraph/estimator.h"
#include "walkgraph/io.h"
#include "walkgraph/pcrb.h"
#include "walkgraph/stance.h"
#include "walkgraph/study.h"

namespace {

namespace fs = std::filesystem;

const char* const kFiles[] = {"walk.yaml", "anchors.csv",      "imu.csv",
                              "rss.csv",   "range.csv",        "odometry.csv",
                              "truth.csv", "stance_truth.csv", "waypoints.csv"};

enum class Reader { kWalk, kConfig, kManifest };

Reader ChosenReader() {
  const char* env = std::getenv("WALKGRAPH_FUZZ_READER");
  const std::string r = env ? env : "walk";
  if (r == "config") return Reader::kConfig;
  if (r == "manifest") return Reader::kManifest;
  return Reader::kWalk;
}

struct Fixture {
  fs::path dir;
  std::map<std::string, std::string> originals;
};

Fixture& GetFixture() {
  static Fixture f = [] {
    Fixture fx;
    fx.dir = fs::temp_directory_path() / ("wg_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(fx.dir);
    const std::string walk =
        "format_version: 1\nname: f\nimu_placement: waist\ntruth: continuous\n"
        "radio: {kind: rss, units: dbm}\n";
    fx.originals = {{"walk.yaml", walk},
                    {"anchors.csv", "id,x_m,y_m,z_m\n1,0,0,2\n2,10,0,2\n"},
                    {"imu.csv", "t_s,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.1,0,0,9.8,0,0,0\n"},
                    {"rss.csv", "t_s,anchor_id,rss\n0,1,-60\n0,2,-70\n"},
                    {"range.csv", "t_s,anchor_id,range_m\n0,1,3\n"},
                    {"odometry.csv", "t_s,dist_m,dheading_rad\n0.5,0.7,0\n"},
                    {"truth.csv", "t_s,x_m,y_m\n0,0,0\n1,1,0\n"},
                    {"stance_truth.csv", "t_s,stance\n0,1\n"},
                    {"waypoints.csv", "t_s,x_m,y_m,sigma_m\n0.5,0.5,0,0.3\n"}};
    for (const auto& [name, text] : fx.originals) std::ofstream(fx.dir / name) << text;
    return fx;
  }();
  return f;
}

void FuzzWalk(const uint8_t* data, size_t size) {
  if (size == 0) return;
  Fixture& fx = GetFixture();
  const std::string name = kFiles[data[0] % std::size(kFiles)];
  {
    std::ofstream out(fx.dir / name, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  }
  const auto walk = walkgraph::ReadWalk(fx.dir.string());
  // Readers and the in-memory validator must agree on what is valid.
  if (walk.ok() && !walkgraph::ValidateWalk(*walk).ok()) __builtin_trap();
  std::ofstream(fx.dir / name, std::ios::binary | std::ios::trunc) << fx.originals.at(name);
}

void FuzzConfig(const std::string& text) {
  auto node = walkgraph::LoadYamlText(text, "config.yaml");
  if (!node.ok()) return;
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const std::string& id : registry.Ids()) (void)registry.Create(id, *node);
  (void)walkgraph::PcrbOptionsFromYaml(*node, "config.yaml");
  (void)walkgraph::StanceOptionsFromYaml(*node);
}

void FuzzManifest(const std::string& text) {
  (void)walkgraph::ParseStudyManifest(text, (GetFixture().dir / "study.yaml").string());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Reader reader = ChosenReader();
  const std::string text(reinterpret_cast<const char*>(data), size);
  switch (reader) {
    case Reader::kWalk:
      FuzzWalk(data, size);
      break;
    case Reader::kConfig:
      FuzzConfig(text);
      break;
    case Reader::kManifest:
      FuzzManifest(text);
      break;
  }
  return 0;
}
