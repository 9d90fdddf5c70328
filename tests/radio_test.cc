#include "walkgraph/radio.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <Eigen/LU>

#include "walkgraph/angle.h"

namespace walkgraph {
namespace {

std::vector<Eigen::Vector2d> GridAnchors() {  // 000 Sec. IV: 9 anchors on a grid over 400 m²
  std::vector<Eigen::Vector2d> a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a.emplace_back(10.0 * i, 10.0 * j);
  return a;
}

std::vector<AnchorRange> Ranges(const std::vector<Eigen::Vector2d>& anchors,
                                const Eigen::Vector2d& x, double sigma, std::mt19937_64* rng) {
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<AnchorRange> out;
  for (size_t i = 0; i < anchors.size(); ++i) {
    AnchorRange m;
    m.anchor_id = static_cast<int>(i);
    m.anchor_m = anchors[i];
    m.range_m = std::max((x - anchors[i]).norm() + n(*rng), 0.0);
    m.sigma_m = sigma;
    out.push_back(m);
  }
  return out;
}

TEST(RadioTest, ExactRangesGiveExactPositions) {
  const auto anchors = GridAnchors();
  std::mt19937_64 rng(1);
  const Eigen::Vector2d x(7.3, 12.1);
  const auto r = Ranges(anchors, x, 1e-12, &rng);
  const FixResult h = HyperbolicFix(r), n = NonlinearLsFix(r);
  ASSERT_TRUE(h.ok()) << h.reason;
  ASSERT_TRUE(n.ok()) << n.reason;
  EXPECT_LT((h.fix.position_m - x).norm(), 1e-6);
  EXPECT_LT((n.fix.position_m - x).norm(), 1e-6);
  EXPECT_EQ(n.fix.num_anchors, 9);
}

// Error statistics consistent with the model: mean NEES ≈ 2 (2-D), and the NLS error below the
// hyperbolic one (the linearisation loses information).
TEST(RadioTest, GaussianRangeErrorsAreConsistentWithCovariance) {
  const auto anchors = GridAnchors();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(2.0, 18.0);
  const int trials = 2000;
  double nees_h = 0, nees_n = 0, mse_h = 0, mse_n = 0;
  for (int k = 0; k < trials; ++k) {
    const Eigen::Vector2d x(u(rng), u(rng));
    const auto r = Ranges(anchors, x, 0.5, &rng);
    const FixResult h = HyperbolicFix(r), n = NonlinearLsFix(r);
    ASSERT_TRUE(h.ok() && n.ok());
    const Eigen::Vector2d eh = h.fix.position_m - x, en = n.fix.position_m - x;
    nees_h += eh.dot(h.fix.covariance.inverse() * eh);
    nees_n += en.dot(n.fix.covariance.inverse() * en);
    mse_h += eh.squaredNorm();
    mse_n += en.squaredNorm();
  }
  nees_h /= trials;
  nees_n /= trials;
  EXPECT_NEAR(nees_n, 2.0, 0.2);
  EXPECT_NEAR(nees_h, 2.0, 0.3);
  EXPECT_LT(mse_n, mse_h);
  EXPECT_LT(std::sqrt(mse_n / trials), 0.5);
}

TEST(RadioTest, LogNormalRangesMatchTheHyperbolicModel) {
  // RSS → ML range with σ = 5 dB, η = 2.5 (000 Sec. IV): σ_d = σ ln10 / (10 η) = 0.46.
  const auto anchors = GridAnchors();
  PathLossParams p;
  p.A_dbm = -60;
  p.eta = 2.5;
  p.sigma_db = 5.0;
  const PathLossModel model(p, RssUnits::kDbm);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> shadow(0.0, p.sigma_db);
  std::uniform_real_distribution<double> u(3.0, 17.0);
  const int trials = 1000;
  int ok = 0;
  std::vector<double> err;
  for (int k = 0; k < trials; ++k) {
    const Eigen::Vector2d x(u(rng), u(rng));
    std::vector<AnchorRange> r;
    for (size_t i = 0; i < anchors.size(); ++i) {
      const double rss = model.ExpectedRss((x - anchors[i]).norm()) + shadow(rng);
      AnchorRange m;
      m.anchor_id = static_cast<int>(i);
      m.anchor_m = anchors[i];
      m.range_m = model.MlRange(rss);
      m.sigma_m = model.RangeSigma(m.range_m);
      r.push_back(m);
    }
    const FixResult h = HyperbolicFix(r);
    if (!h.ok()) continue;
    ++ok;
    ASSERT_TRUE(h.fix.position_m.allFinite());
    err.push_back((h.fix.position_m - x).norm());
  }
  EXPECT_EQ(ok, trials);
  std::sort(err.begin(), err.end());
  const double median = err[err.size() / 2];
  // Range errors are ≈46 % of distance: metre-level medians, bounded by the 20 m area.
  EXPECT_GT(median, 1.0);
  EXPECT_LT(median, 6.0);
}

TEST(RadioTest, DegenerateGeometryIsNoFixNeverNan) {
  std::mt19937_64 rng(3);
  const Eigen::Vector2d x(1.0, 2.0);
  const auto two = Ranges({{0, 0}, {10, 0}}, x, 0.1, &rng);
  EXPECT_EQ(HyperbolicFix(two).status, FixStatus::kTooFewAnchors);
  EXPECT_EQ(NonlinearLsFix(two).status, FixStatus::kTooFewAnchors);
  const auto line = Ranges({{0, 0}, {5, 0}, {10, 0}, {15, 0.01}}, x, 0.1, &rng);
  EXPECT_EQ(HyperbolicFix(line).status, FixStatus::kCollinear);
  EXPECT_EQ(NonlinearLsFix(line).status, FixStatus::kCollinear);
  // The same anchor three times counts once.
  auto same = Ranges({{0, 0}, {10, 0}, {0, 10}}, x, 0.1, &rng);
  same[1].anchor_id = 0;
  same[2].anchor_id = 0;
  EXPECT_EQ(NonlinearLsFix(same).status, FixStatus::kTooFewAnchors);
  EXPECT_FALSE(NonlinearLsFix({}).ok());
  // NaN input readings are dropped, not propagated.
  auto nan = Ranges({{0, 0}, {10, 0}, {0, 10}, {10, 10}}, x, 0.1, &rng);
  nan[3].range_m = std::nan("");
  const FixResult f = NonlinearLsFix(nan);
  ASSERT_TRUE(f.ok()) << f.reason;
  EXPECT_TRUE(f.fix.position_m.allFinite());
  EXPECT_TRUE(f.fix.covariance.allFinite());
}

TEST(RadioTest, EpochsGroupReadingsAndAverageRss) {
  Walk w;
  w.meta.radio.kind = RadioKind::kRss;
  w.meta.radio.path_loss.A_dbm = -60;
  w.meta.radio.path_loss.eta = 2.0;
  w.anchors = {{1, {0, 0, 0}}, {2, {10, 0, 0}}, {3, {0, 10, 0}}};
  w.rss = {{0.1, 1, -70}, {0.2, 1, -74}, {0.5, 2, -80}, {0.9, 3, -80}, {1.2, 1, -60}};
  auto e = BuildRangeEpochs(w, EpochOptions());
  ASSERT_TRUE(e.ok()) << e.status().ToString();
  ASSERT_EQ(e->size(), 2u);
  ASSERT_EQ((*e)[0].ranges.size(), 3u);
  EXPECT_NEAR((*e)[0].ranges[0].range_m, std::pow(10.0, 12.0 / 20.0), 1e-9);  // mean −72 dBm
  EXPECT_DOUBLE_EQ((*e)[0].max_rss, -72.0);
  EXPECT_NEAR((*e)[0].t_s, (0.1 + 0.2 + 0.5 + 0.9) / 4, 1e-12);
  auto fixes = PositionWalk(w, EpochOptions(), PositioningMethod::kNonlinearLs);
  ASSERT_TRUE(fixes.ok());
  ASSERT_EQ(fixes->size(), 2u);
  EXPECT_TRUE((*fixes)[0].ok());
  EXPECT_EQ((*fixes)[1].status, FixStatus::kTooFewAnchors);
  w.rss.push_back({1.3, 9, -60});
  EXPECT_FALSE(BuildRangeEpochs(w, EpochOptions()).ok());
}

TEST(RadioTest, PathLossFitRecoversSimulatedParameters) {
  PathLossParams p;
  p.A_dbm = -55;
  p.eta = 2.2;
  p.sigma_db = 4.0;
  const PathLossModel model(p, RssUnits::kDbm);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> shadow(0.0, p.sigma_db);
  std::uniform_real_distribution<double> d(0.5, 20.0);
  std::vector<PathLossObservation> obs;
  for (int i = 0; i < 5000; ++i) {
    const double di = d(rng);
    obs.push_back({i % 2, di, model.ExpectedRss(di) + shadow(rng) + (i % 2 ? 3.0 : 0.0)});
  }
  auto g = FitPathLoss(obs, RssUnits::kDbm);
  ASSERT_TRUE(g.ok());
  EXPECT_NEAR(g->params.A_dbm, -53.5, 0.3);
  EXPECT_NEAR(g->params.eta, 2.2, 0.05);
  EXPECT_NEAR(g->params.sigma_db, std::sqrt(16.0 + 2.25), 0.15);
  auto per = FitPathLossPerAnchor(obs, RssUnits::kDbm);
  ASSERT_TRUE(per.ok());
  ASSERT_EQ(per->size(), 2u);
  EXPECT_NEAR((*per)[0].params.A_dbm, -55.0, 0.4);
  EXPECT_NEAR((*per)[1].params.A_dbm, -52.0, 0.4);
  EXPECT_NEAR((*per)[1].params.sigma_db, 4.0, 0.15);
  // RFCode units (004): RSS grows with distance; RSS0 = 60, p = 2.3.
  PathLossParams q;
  q.A_dbm = 60;
  q.eta = 2.3;
  q.sigma_db = 6;
  const PathLossModel rf(q, RssUnits::kRfcode);
  std::vector<PathLossObservation> obs2;
  for (int i = 0; i < 5000; ++i) {
    const double di = d(rng);
    obs2.push_back({0, di, rf.ExpectedRss(di) + 6.0 * shadow(rng) / 4.0});
  }
  auto f2 = FitPathLoss(obs2, RssUnits::kRfcode);
  ASSERT_TRUE(f2.ok());
  EXPECT_NEAR(f2->params.eta, 2.3, 0.08);
  EXPECT_NEAR(f2->params.A_dbm, 60.0, 0.5);
  EXPECT_FALSE(FitPathLoss({{0, 2.0, -60}, {0, 2.0, -61}, {0, 2.0, -62}}, RssUnits::kDbm).ok());
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string field;
  while (std::getline(ss, field, ',')) out.push_back(field);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

void PrintFits(const char* name, const PathLossFit& global, const std::vector<PathLossFit>& per) {
  std::printf("%s global: A = %.2f dBm, eta = %.3f, sigma = %.2f dB (n = %d)\n", name,
              global.params.A_dbm, global.params.eta, global.params.sigma_db,
              global.num_observations);
  for (const PathLossFit& f : per) {
    std::printf("%s anchor %d: A = %.2f dBm, eta = %.3f, sigma = %.2f dB (n = %d)\n", name,
                f.anchor_id, f.params.A_dbm, f.params.eta, f.params.sigma_db, f.num_observations);
  }
}

// Real data (Kolakowski 2021): 6 BLE anchors, a robot-carried receiver at LiDAR-SLAM positions.
// The receiver height is not documented; 0.3 m (a small robot) is assumed.
TEST(RadioRealData, BleCalib2021PathLoss) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/ble_calib2021";
  std::ifstream anchors_in(dir + "/anchors.csv"), df(dir + "/calibration/calibration_df.csv");
  if (!anchors_in || !df) GTEST_SKIP() << dir << " not present";
  std::map<int, Eigen::Vector3d> anchors;
  std::string line;
  std::getline(anchors_in, line);
  while (std::getline(anchors_in, line)) {
    const auto f = SplitCsv(line);
    ASSERT_EQ(f.size(), 4u) << line;
    anchors[std::stoi(f[0])] = Eigen::Vector3d(std::stod(f[1]), std::stod(f[2]), std::stod(f[3]));
  }
  std::getline(df, line);
  const auto header = SplitCsv(line);
  ASSERT_EQ(header.size(), 11u);
  ASSERT_EQ(header[2], "x");
  ASSERT_EQ(header[4], "y");
  std::vector<PathLossObservation> obs;
  while (std::getline(df, line)) {
    const auto f = SplitCsv(line);
    ASSERT_EQ(f.size(), 11u) << line;
    const Eigen::Vector3d rx(std::stod(f[2]), std::stod(f[4]), 0.3);
    for (int a = 1; a <= 6; ++a) {
      if (f[4 + a].empty()) continue;
      obs.push_back({a, (anchors.at(a) - rx).norm(), std::stod(f[4 + a])});
    }
  }
  auto global = FitPathLoss(obs, RssUnits::kDbm);
  auto per = FitPathLossPerAnchor(obs, RssUnits::kDbm);
  ASSERT_TRUE(global.ok() && per.ok());
  PrintFits("ble_calib2021", *global, *per);
  EXPECT_EQ(per->size(), 6u);
  // Indoor BLE: exponent between free space-ish and heavy loss, shadowing of a few dB.
  EXPECT_GT(global->params.eta, 1.0);
  EXPECT_LT(global->params.eta, 4.0);
  EXPECT_GT(global->params.sigma_db, 3.0);
  EXPECT_LT(global->params.sigma_db, 10.0);
  for (const PathLossFit& f : *per) {
    EXPECT_GT(f.params.eta, 0.5) << f.anchor_id;
    EXPECT_LT(f.params.eta, 5.0) << f.anchor_id;
    EXPECT_LT(f.params.sigma_db, 10.0) << f.anchor_id;
  }
}

// Real data (Daniş et al. 2022): a carried beacon heard by 12 receivers; AR-tag positions.
TEST(RadioRealData, BleTracksPathLoss) {
  const std::string dir = std::string(WALKGRAPH_SHARED_DATASETS) + "/ble_tracks";
  std::ifstream dev(dir + "/cnf/tetam.dev");
  if (!dev) GTEST_SKIP() << dir << " not present";
  // Dongles:{"b827eb4521b4": [[7.00, 7.09, 1.22], 16711680, "sensor10"], ...}
  std::map<std::string, std::pair<int, Eigen::Vector3d>> receivers;
  std::string line;
  while (std::getline(dev, line)) {
    if (line.rfind("Dongles:", 0) != 0) continue;
    size_t pos = 0;
    while ((pos = line.find('"', pos)) != std::string::npos) {
      const size_t end = line.find('"', pos + 1);
      const std::string key = line.substr(pos + 1, end - pos - 1);
      const size_t open = line.find("[[", end);
      if (open == std::string::npos) break;
      double x, y, z;
      ASSERT_EQ(std::sscanf(line.c_str() + open, "[[%lf, %lf, %lf]", &x, &y, &z), 3) << key;
      const size_t alias = line.find("\"sensor", open);
      const int id = std::stoi(line.substr(alias + 7, 2));
      receivers[key] = {id, Eigen::Vector3d(x, y, z)};
      pos = line.find('"', alias + 1) + 1;
    }
  }
  ASSERT_EQ(receivers.size(), 12u);
  std::vector<PathLossObservation> obs;
  for (const char* trk :
       {"rectangular_without_rotation_all_sensors.mbd", "straight_01_all_sensors.mbd",
        "straight_02_all_sensors.mbd", "straight_03_all_sensors.mbd", "straight_04_all_sensors.mbd",
        "zigzagging_without_rotation_all_sensors.mbd"}) {
    std::ifstream in(dir + "/trk/" + trk);
    ASSERT_TRUE(in) << trk;
    while (std::getline(in, line)) {
      const auto f = SplitCsv(line);
      ASSERT_GE(f.size(), 7u) << trk << ": " << line;
      const auto it = receivers.find(f[1]);
      ASSERT_NE(it, receivers.end()) << trk << ": unknown receiver " << f[1];
      const Eigen::Vector3d beacon(std::stod(f[4]), std::stod(f[5]), std::stod(f[6]));
      obs.push_back({it->second.first, (beacon - it->second.second).norm(), std::stod(f[3])});
    }
  }
  auto global = FitPathLoss(obs, RssUnits::kDbm);
  auto per = FitPathLossPerAnchor(obs, RssUnits::kDbm);
  ASSERT_TRUE(global.ok() && per.ok());
  PrintFits("ble_tracks", *global, *per);
  EXPECT_EQ(per->size(), 12u);
  EXPECT_GT(global->params.eta, 0.5);
  EXPECT_LT(global->params.eta, 4.0);
  EXPECT_GT(global->params.sigma_db, 3.0);
  EXPECT_LT(global->params.sigma_db, 10.0);
}

}  // namespace
}  // namespace walkgraph
