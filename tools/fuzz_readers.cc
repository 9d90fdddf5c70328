// libFuzzer target for the walk readers (CSV and YAML). Built with -DWALKGRAPH_FUZZ=ON under
// clang. Each input replaces one file of a valid walk (chosen by the first byte) and ReadWalk
// must return a Status — never crash, hang or trip a sanitizer.
//
//   CC=clang CXX=clang++ cmake -S . -B build-fuzz -DWALKGRAPH_FUZZ=ON -DWALKGRAPH_BUILD_TESTS=OFF
//   cmake --build build-fuzz --target fuzz_readers
//   ./build-fuzz/tools/fuzz_readers -max_total_time=600 tests/data/walks/valid_small
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "walkgraph/io.h"

namespace {

namespace fs = std::filesystem;

const char* const kFiles[] = {"walk.yaml", "anchors.csv", "imu.csv",  "rss.csv",
                              "range.csv", "odometry.csv", "truth.csv", "stance_truth.csv"};

struct Fixture {
  fs::path dir;
  std::map<std::string, std::string> originals;
};

Fixture& GetFixture() {
  static Fixture f = [] {
    Fixture fx;
    fx.dir = fs::temp_directory_path() / ("wg_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(fx.dir);
    const std::string walk = "format_version: 1\nname: f\nimu_placement: waist\ntruth: continuous\n"
                             "radio: {kind: rss, units: dbm}\n";
    fx.originals = {{"walk.yaml", walk},
                    {"anchors.csv", "id,x_m,y_m,z_m\n1,0,0,2\n2,10,0,2\n"},
                    {"imu.csv", "t_s,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.1,0,0,9.8,0,0,0\n"},
                    {"rss.csv", "t_s,anchor_id,rss\n0,1,-60\n0,2,-70\n"},
                    {"range.csv", "t_s,anchor_id,range_m\n0,1,3\n"},
                    {"odometry.csv", "t_s,dist_m,dheading_rad\n0.5,0.7,0\n"},
                    {"truth.csv", "t_s,x_m,y_m\n0,0,0\n1,1,0\n"},
                    {"stance_truth.csv", "t_s,stance\n0,1\n"}};
    for (const auto& [name, text] : fx.originals) std::ofstream(fx.dir / name) << text;
    return fx;
  }();
  return f;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  Fixture& fx = GetFixture();
  const std::string name = kFiles[data[0] % std::size(kFiles)];
  {
    std::ofstream out(fx.dir / name, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  }
  const auto walk = walkgraph::ReadWalk(fx.dir.string());
  if (walk.ok() && !walkgraph::ValidateWalk(*walk).ok()) __builtin_trap();  // readers and
  // the in-memory validator must agree on what is valid
  std::ofstream(fx.dir / name, std::ios::binary | std::ios::trunc) << fx.originals.at(name);
  return 0;
}
