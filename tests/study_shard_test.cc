// Studies in parts (study.h): the split of the cells, a part's bytes, merging, failures.
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/reader.h"
#include "walkgraph/config.h"
#include "walkgraph/study.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::atomic<int> g_runs{0};

// Test-only estimator: the truth shifted along x by offset_m, plus (seed mod 1000) mm when
// `seeded`, so each run's figures differ and a cell's mean depends on every one of its runs.
class Shifted : public Estimator {
 public:
  Shifted(double offset, bool seeded, bool fails)
      : offset_(offset), seeded_(seeded), fails_(fails) {}
  Status CheckApplicable(const Walk& w) const override {
    return w.has_truth() ? Status::Ok() : FailedPrecondition("needs truth");
  }
  StatusOr<EstimateResult> Run(const Walk& w) const override {
    ++g_runs;
    if (fails_) return NumericalError("failed on purpose");
    double d = offset_;
    if (seeded_)
      d += static_cast<double>(static_cast<uint64_t>(w.meta.extra.at("sim.seed")) % 1000) / 1000.0;
    EstimateResult r;
    for (const TruthSample& t : w.truth) {
      TrajectoryPoint p;
      p.t_s = t.t_s;
      p.position_m = Eigen::Vector3d(t.position_m.x() + d, t.position_m.y() + 0.1 * d, 0.0);
      r.trajectory.points.push_back(p);
    }
    return r;
  }

 private:
  double offset_;
  bool seeded_, fails_;
};

const EstimatorRegistry& Registry() {
  static const EstimatorRegistry* r = [] {
    auto* reg = new EstimatorRegistry();
    for (const auto& [id, seeded, fails] :
         {std::tuple<const char*, bool, bool>{"offset", false, false},
          {"seeded", true, false},
          {"fails", false, true}}) {
      const bool s = seeded, f = fails;
      EXPECT_TRUE(
          reg->Register({id, "test",
                         [s, f](const Config& config) -> StatusOr<std::unique_ptr<Estimator>> {
                           double v = 0.3;
                           ConfigReader cr(config.node(), "test");
                           cr.Read("offset_m", &v);
                           WG_RETURN_IF_ERROR(cr.Finish());
                           return std::unique_ptr<Estimator>(new Shifted(v, s, f));
                         }})
              .ok());
    }
    return reg;
  }();
  return *r;
}

// 3 + 4 + 1 cells of different costs (runs × estimators).
const char* const kManifest = R"(name: parts
estimators: [offset, seeded]
runs: 3
seed: 7
sweeps:
  - name: opt
    scenario: linear-gaussian
    overrides: {duration_s: 8}
    estimator_option: offset_m
    values: [0.1, 0.25, 0.5]
  - name: sim
    scenario: linear-gaussian
    overrides: {duration_s: 8}
    scenario_override: range_sigma_m
    estimators: [seeded, fails]
    values: [0.2, 0.4, 0.8, 1.6]
    runs: 5
  - name: one
    scenario: linear-gaussian
    overrides: {duration_s: 8}
    estimator_option: offset_m
    values: [2]
    runs: 1
)";

StudyManifest Manifest(const std::string& text = kManifest) {
  auto m = ParseStudyManifest(text, "parts.yaml", Registry());
  EXPECT_TRUE(m.ok()) << m.status().message();
  return *m;
}

TEST(StudyShard, ParsesIOverNAndRefusesTheRest) {
  auto s = ParseStudyShard("3/16");
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->index, 3);
  EXPECT_EQ(s->count, 16);
  for (const char* bad : {"", "3", "16/16", "-1/4", "1/0", "a/b", "1/2/3", " 1/2", "1/"}) {
    EXPECT_FALSE(ParseStudyShard(bad).ok()) << bad;
  }
}

TEST(StudyShard, EveryCellInExactlyOnePartForAnyN) {
  const StudyManifest m = Manifest();
  for (int n = 1; n <= 10; ++n) {
    std::multiset<int> seen;
    long long max_cost = 0, min_cost = 1LL << 40;
    for (int i = 0; i < n; ++i) {
      const std::vector<int> cells = StudyShardCells(m, {i, n});
      EXPECT_TRUE(std::is_sorted(cells.begin(), cells.end()));
      EXPECT_EQ(cells, StudyShardCells(m, {i, n}));  // deterministic
      long long cost = 0;
      for (int c : cells) {
        seen.insert(c);
        cost += c < 3 ? 6 : (c < 7 ? 10 : 2);
      }
      max_cost = std::max(max_cost, cost);
      min_cost = std::min(min_cost, cost);
    }
    EXPECT_EQ(seen.size(), 8u) << n;
    EXPECT_EQ(std::set<int>(seen.begin(), seen.end()).size(), 8u) << n;
    // Largest first, each to the lightest part: the parts' costs (60 in all) differ by at most
    // the largest cell's (10).
    EXPECT_LE(max_cost - min_cost, 10) << n;
    if (n >= 8) EXPECT_EQ(max_cost, 10) << "one cell per part";
  }
}

TEST(StudyShard, PartsMergeToTheBytesOfTheWholeRun) {
  const StudyManifest m = Manifest();
  auto whole = RunStudy(m, {}, Registry());
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  const std::string csv = StudyCsv(*whole), html = RenderStudyHtml(*whole);
  ASSERT_NE(csv.find("\nsim,"), std::string::npos);
  for (int n : {2, 3, 5, 9}) {
    std::vector<StudyPart> parts;
    for (int i = n - 1; i >= 0; --i) {  // any order
      StudyOptions threads;
      threads.threads = 1 + i % 3;
      auto part = RunStudyPart(m, {i, n}, threads, Registry());
      ASSERT_TRUE(part.ok()) << part.status().message();
      // Through bytes, as between processes.
      auto back = ParseStudyPart(SerializeStudyPart(*part), "part");
      ASSERT_TRUE(back.ok()) << back.status().message();
      EXPECT_EQ(SerializeStudyPart(*back), SerializeStudyPart(*part));
      parts.push_back(std::move(back).value());
    }
    auto merged = MergeStudyParts(m, parts);
    ASSERT_TRUE(merged.ok()) << merged.status().message();
    EXPECT_EQ(StudyCsv(*merged), csv) << n;
    EXPECT_EQ(RenderStudyHtml(*merged), html) << n;
  }
}

// The MPI ranks claim cells from a shared counter as they finish (StudyOptions::claim_cell):
// which part runs which cell then depends on timing, the merged bytes must not. Here each part
// gets an arbitrary share of the claim positions (parts run one after the other: the manifest's
// YAML nodes are not for concurrent reading within one process; MPI ranks are processes).
TEST(StudyShard, ClaimedPartsMergeToTheBytesOfTheWholeRun) {
  const StudyManifest m = Manifest();
  auto whole = RunStudy(m, {}, Registry());
  ASSERT_TRUE(whole.ok()) << whole.status().message();
  const int cells = static_cast<int>(whole->cells.size());
  for (int n : {2, 3}) {
    std::vector<std::vector<int>> claims(n);  // claim positions of each part, in order
    for (int at = 0; at < cells; ++at)
      claims[(at * at) % n].push_back(at);  // uneven, some parts none
    std::vector<StudyPart> parts;
    size_t run = 0;
    for (int i = n - 1; i >= 0; --i) {
      size_t next = 0;
      StudyOptions claim;
      claim.claim_cell = [&claims, &next, i] {
        return next < claims[i].size() ? claims[i][next++] : 1 << 20;
      };
      auto part = RunStudyPart(m, {i, n}, claim, Registry());
      ASSERT_TRUE(part.ok()) << part.status().message();
      EXPECT_TRUE(part->claimed);
      EXPECT_EQ(part->cells.size(), claims[i].size());
      run += part->cells.size();
      auto back = ParseStudyPart(SerializeStudyPart(*part), "part");
      ASSERT_TRUE(back.ok()) << back.status().message();
      EXPECT_TRUE(back->claimed);
      parts.push_back(std::move(back).value());
    }
    EXPECT_EQ(run, whole->cells.size());
    auto merged = MergeStudyParts(m, parts);
    ASSERT_TRUE(merged.ok()) << merged.status().message();
    EXPECT_EQ(StudyCsv(*merged), StudyCsv(*whole)) << n;
    EXPECT_EQ(RenderStudyHtml(*merged), RenderStudyHtml(*whole)) << n;
  }
}

TEST(StudyShard, MergeRefusesClaimedPartsThatMissOrRepeatACell) {
  const StudyManifest m = Manifest();
  int next = 0;
  StudyOptions first;  // claims every cell
  first.claim_cell = [&next] { return next++; };
  auto all = RunStudyPart(m, {0, 2}, first, Registry());
  StudyOptions none;  // claims nothing: the counter is past the last cell
  none.claim_cell = [] { return 1 << 20; };
  auto empty = RunStudyPart(m, {1, 2}, none, Registry());
  ASSERT_TRUE(all.ok() && empty.ok());
  EXPECT_TRUE(empty->cells.empty());
  auto message = [&](std::vector<StudyPart> ps) {
    auto r = MergeStudyParts(m, ps);
    return r.ok() ? std::string("merged") : r.status().message();
  };
  EXPECT_EQ(message({*all, *empty}), "merged");
  StudyPart twice = *all;
  twice.shard.index = 1;
  EXPECT_THAT(message({*all, twice}), HasSubstr("a cell of another part"));
  StudyPart short_of_one = *all;
  short_of_one.cells.pop_back();
  EXPECT_THAT(message({short_of_one, *empty}), HasSubstr("is in no part"));
  auto fixed = RunStudyPart(m, {1, 2}, {}, Registry());
  ASSERT_TRUE(fixed.ok());
  EXPECT_THAT(message({*all, *fixed}), HasSubstr("mixed"));
}

TEST(StudyShard, BytesKeepEveryDoubleExactly) {
  StudyPart p;
  p.shard = {1, 2};
  p.manifest_path = "a b:c.yaml";
  p.manifest_text = "name: x\n  odd: \"1:2 3\"\n";
  StudyCell c;
  c.sweep = 0;
  c.value = 1;
  c.runs = 4;
  c.seed = 18446744073709551615ULL;
  c.pcrb_rmse_m = 0.1 + 0.2;
  c.pcrb_note = "";
  StudyRow ok, bad;
  ok.estimator = "e1";
  ok.stats.rmse_m = std::nextafter(1.0, 2.0);
  ok.stats.anees = std::nan("");
  ok.stats.max_m = -0.0;
  ok.stats.n_points = 12345;
  ok.stats_std = ErrorStats{};
  ok.stats_std->final_m = 1e-310;  // subnormal
  ok.runtime_s = 1.0 / 3.0;
  bad.estimator = "e,2";
  bad.status = NumericalError("diverged: 3 km \"outside\"\nsecond line");
  bad.failed_runs = 4;
  c.rows = {ok, bad};
  p.cells = {c};
  const std::string bytes = SerializeStudyPart(p);
  auto back = ParseStudyPart(bytes, "x");
  ASSERT_TRUE(back.ok()) << back.status().message();
  const StudyCell& d = back->cells.at(0);
  EXPECT_EQ(back->manifest_path, p.manifest_path);
  EXPECT_EQ(back->manifest_text, p.manifest_text);
  EXPECT_EQ(d.seed, c.seed);
  EXPECT_EQ(*d.pcrb_rmse_m, *c.pcrb_rmse_m);
  EXPECT_FALSE(d.pcrb_filter_rmse_m.has_value());
  EXPECT_EQ(d.rows.at(0).stats.rmse_m, ok.stats.rmse_m);
  EXPECT_TRUE(std::isnan(d.rows[0].stats.anees));
  EXPECT_TRUE(std::signbit(d.rows[0].stats.max_m));
  EXPECT_EQ(d.rows[0].stats_std->final_m, 1e-310);
  EXPECT_EQ(d.rows[0].stats.n_points, 12345);
  EXPECT_EQ(d.rows[0].runtime_s, 1.0 / 3.0);
  EXPECT_EQ(d.rows.at(1).status.code(), StatusCode::kNumerical);
  EXPECT_EQ(d.rows[1].status.message(), bad.status.message());
  EXPECT_EQ(d.rows[1].failed_runs, 4);
  EXPECT_FALSE(d.rows[1].stats_std.has_value());
  // Truncated or altered bytes are refused, never half read.
  for (size_t cut : {size_t{0}, size_t{5}, bytes.size() / 2, bytes.size() - 5}) {
    EXPECT_FALSE(ParseStudyPart(bytes.substr(0, cut), "cut").ok()) << cut;
  }
  EXPECT_FALSE(ParseStudyPart(bytes + "x", "tail").ok());
  EXPECT_FALSE(ParseStudyPart("22:walkgraph-study-part 1 0 99999999999999999999 ", "big").ok());
  EXPECT_FALSE(ParseStudyPart("22:walkgraph-study-part 1 -1 2 ", "negative").ok());
  EXPECT_THAT(ParseStudyPart("walkgraph-study-part 2", "old").status().message(),
              HasSubstr("old: not a walkgraph study part"));
}

TEST(StudyShard, MergeRefusesIncompleteOrForeignParts) {
  const StudyManifest m = Manifest();
  std::vector<StudyPart> parts;
  for (int i = 0; i < 3; ++i) {
    auto p = RunStudyPart(m, {i, 3}, {}, Registry());
    ASSERT_TRUE(p.ok());
    parts.push_back(*p);
  }
  auto message = [&](std::vector<StudyPart> ps) {
    auto r = MergeStudyParts(m, ps);
    return r.ok() ? std::string("merged") : r.status().message();
  };
  EXPECT_EQ(message(parts), "merged");
  EXPECT_THAT(message({parts[0], parts[2]}), HasSubstr("study part 1/3 is missing"));
  EXPECT_THAT(message({parts[0], parts[1], parts[1], parts[2]}), HasSubstr("1/3: given twice"));
  auto other = RunStudyPart(m, {0, 2}, {}, Registry());
  ASSERT_TRUE(other.ok());
  EXPECT_THAT(message({parts[0], parts[1], parts[2], *other}), HasSubstr("different splits"));
  std::vector<StudyPart> foreign = parts;
  foreign[1].manifest_text += "# edited\n";
  EXPECT_THAT(message(foreign), HasSubstr("ran another manifest"));
  std::vector<StudyPart> wrong = parts;
  std::swap(wrong[0].cells, wrong[1].cells);
  EXPECT_THAT(message(wrong), HasSubstr("not the cells of that part"));
  EXPECT_THAT(message({}), HasSubstr("no parts"));
}

TEST(StudyShard, AFailingCellNamesItselfAndTheAgreementStopsThePartBeforeAnyRun) {
  // range_sigma_m -1 is refused by the simulator: the cell's validation fails.
  std::string text = kManifest;
  text.replace(text.find("1.6]"), 4, "-1]");
  const StudyManifest m = Manifest(text);
  int failed = 0;
  for (int i = 0; i < 3; ++i) {
    StudyOptions o;
    int calls = 0;
    Status seen;
    o.validated = [&](const Status& v) {
      ++calls;
      seen = v;
      return Cancelled("another part failed");
    };
    const int before = g_runs;
    auto p = RunStudyPart(m, {i, 3}, o, Registry());
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(g_runs, before) << "nothing runs after a failed agreement";
    ASSERT_FALSE(p.ok());
    if (!seen.ok()) {
      ++failed;
      EXPECT_THAT(seen.message(), HasSubstr("parts.yaml:16: sweep 'sim', value -1"));
      EXPECT_EQ(p.status().message(), seen.message()) << "its own failure, not the agreement's";
    } else {
      EXPECT_EQ(p.status().message(), "another part failed");
    }
  }
  EXPECT_EQ(failed, 1);
}

TEST(StudyShard, PartFoldersMergeFromDisk) {
  const StudyManifest m = Manifest();
  const fs::path dir = fs::temp_directory_path() / ("wg-parts-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  std::vector<std::string> paths;
  for (int i = 0; i < 2; ++i) {
    auto p = RunStudyPart(m, {i, 2}, {}, Registry());
    ASSERT_TRUE(p.ok());
    paths.push_back((dir / ("part" + std::to_string(i))).string());
    ASSERT_TRUE(WriteStudyPart(*p, paths.back()).ok());
    EXPECT_TRUE(fs::exists(fs::path(paths.back()) / kOutputMarker));
  }
  paths[1] = (fs::path(paths[1]) / kStudyPartFile).string();  // a folder or its file
  auto merged = MergeStudyPartFiles(paths, Registry());
  ASSERT_TRUE(merged.ok()) << merged.status().message();
  auto whole = RunStudy(m, {}, Registry());
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(StudyCsv(*merged), StudyCsv(*whole));
  EXPECT_FALSE(MergeStudyPartFiles({paths[0]}, Registry()).ok());
  EXPECT_FALSE(MergeStudyPartFiles({(dir / "none").string()}, Registry()).ok());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace walkgraph
