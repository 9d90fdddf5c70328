#include "walkgraph/simulate.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "factors/barometric_height_factor.h"
#include "walkgraph/angle.h"
#include "walkgraph/io.h"
#include "walkgraph/path_loss.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;

std::string ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Mean and standard deviation.
std::pair<double, double> Stats(const std::vector<double>& v) {
  double m = 0.0;
  for (double x : v) m += x;
  m /= v.size();
  double q = 0.0;
  for (double x : v) q += (x - m) * (x - m);
  return {m, std::sqrt(q / (v.size() - 1))};
}

// Truth position at t (linear interpolation).
Eigen::Vector3d TruthAt(const Walk& w, double t) {
  auto it = std::lower_bound(w.truth.begin(), w.truth.end(), t,
                             [](const TruthSample& s, double x) { return s.t_s < x; });
  if (it == w.truth.begin()) return it->position_m;
  if (it == w.truth.end()) return w.truth.back().position_m;
  const TruthSample& b = *it;
  const TruthSample& a = *(it - 1);
  const double u = (t - a.t_s) / (b.t_s - a.t_s);
  return a.position_m + u * (b.position_m - a.position_m);
}

TEST(Simulate, EveryPresetSimulatesAndValidates) {
  ASSERT_EQ(Scenarios().size(), 10u);  // issue 41 added handheld-phone
  for (const ScenarioInfo& info : Scenarios()) {
    SCOPED_TRACE(info.name);
    auto w = SimulateScenario(info.name, 7);
    ASSERT_TRUE(w.ok()) << w.status().message();
    EXPECT_TRUE(ValidateWalk(*w).ok()) << ValidateWalk(*w).message();
    ASSERT_TRUE(w->meta.initial_pose.has_value());
    EXPECT_NEAR(w->meta.initial_pose->x_m, w->truth.front().position_m.x(), 1e-6);
    EXPECT_NEAR(w->meta.initial_pose->y_m, w->truth.front().position_m.y(), 1e-6);
    EXPECT_EQ(w->meta.extra.at("sim.seed"), 7.0);
    EXPECT_TRUE(w->has_rss() || w->has_ranges());
  }
}

TEST(Simulate, SameSeedGivesByteIdenticalFilesAndOtherSeedDiffers) {
  const fs::path root = fs::temp_directory_path() / ("wg_sim_" + std::to_string(::getpid()));
  fs::remove_all(root);
  for (const ScenarioInfo& info : Scenarios()) {
    SCOPED_TRACE(info.name);
    const YAML::Node o = YAML::Load("{duration_s: 40}");
    for (int run = 0; run < 2; ++run) {
      auto w = SimulateScenario(info.name, 11, o);
      ASSERT_TRUE(w.ok()) << w.status().message();
      ASSERT_TRUE(WriteWalk(*w, (root / (info.name + std::to_string(run))).string()).ok());
    }
    auto other = SimulateScenario(info.name, 12, o);
    ASSERT_TRUE(other.ok());
    ASSERT_TRUE(WriteWalk(*other, (root / (info.name + "x")).string()).ok());
    int files = 0;
    bool any_difference = false;
    for (const auto& e : fs::directory_iterator(root / (info.name + "0"))) {
      const std::string a = ReadBytes(e.path());
      EXPECT_EQ(a, ReadBytes(root / (info.name + "1") / e.path().filename()))
          << e.path().filename();
      const fs::path px = root / (info.name + "x") / e.path().filename();
      if (e.path().filename() != "anchors.csv" && fs::exists(px) && ReadBytes(px) != a) {
        any_difference = true;
      }
      ++files;
    }
    EXPECT_GE(files, 3);
    EXPECT_TRUE(any_difference);
    auto reread = ReadWalk((root / (info.name + "0")).string());
    EXPECT_TRUE(reread.ok()) << reread.status().message();
  }
  fs::remove_all(root);
}

TEST(Simulate, RejectsUnknownScenarioAndKeys) {
  EXPECT_EQ(SimulateScenario("no-such", 1).status().code(), StatusCode::kNotFound);
  auto bad = SimulateScenario("tarrio-circle", 1, YAML::Load("{etaa: 3}"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("etaa"), std::string::npos);
  EXPECT_FALSE(SimulateScenario("tarrio-circle", 1, YAML::Load("{eta: -1}")).ok());
  // TOA keys only exist where TOA is simulated.
  EXPECT_FALSE(SimulateScenario("tarrio-circle", 1, YAML::Load("{toa_sigma_m: 1}")).ok());
  auto ok = SimulateScenario("tarrio-circle", 1, YAML::Load("{eta: 3.0, num_anchors: 4}"));
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok->meta.radio.path_loss.eta, 3.0);
  EXPECT_EQ(ok->anchors.size(), 4u);
}

// RSS residuals against the configured model (000: A = −60, η = 2.5, σ = 5 dB), close to the
// anchors where the −95 dBm sensitivity cannot truncate the distribution (≥ 3.5σ margin).
TEST(Simulate, RssResidualsMatchThePathLossModel) {
  std::vector<double> res;
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    auto w = SimulateScenario("tarrio-circle", seed);
    ASSERT_TRUE(w.ok());
    const PathLossModel model(w->meta.radio.path_loss, w->meta.radio.units);
    EXPECT_EQ(model.params().A_dbm, -60.0);
    for (const RssSample& s : w->rss) {
      const Eigen::Vector3d a = w->anchors[w->AnchorIndex(s.anchor_id)].position_m;
      const double d = (TruthAt(*w, s.t_s) - a).norm();
      if (d < 5.0) res.push_back(s.rss - model.ExpectedRss(d));
    }
  }
  ASSERT_GT(res.size(), 500u);
  const auto [mean, sigma] = Stats(res);
  std::printf("RSS residual (d < 5 m, n = %zu): mean %.3f dB, sigma %.3f dB\n", res.size(), mean,
              sigma);
  EXPECT_NEAR(mean, 0.0, 4.0 * 5.0 / std::sqrt(res.size()));
  EXPECT_NEAR(sigma, 5.0, 0.25);
}

TEST(Simulate, StepFrequencyLengthAndAmplitudeFollow000) {
  auto s = SimulateScenarioDetailed("tarrio-circle", 5);
  ASSERT_TRUE(s.ok());
  const double l = 0.32 + 0.26 * 1.0;  // 000 Sec. IV at v = 1 m/s
  std::vector<double> len, dur;
  for (const auto& e : s->steps) {
    if (e.t_s > 1.0) {
      len.push_back(e.length_m);
      dur.push_back(e.duration_s);
    }
  }
  const auto [ml, sl] = Stats(len);
  const auto [md, sd] = Stats(dur);
  std::printf("steps: %zu, length %.4f m (model %.4f), frequency %.4f Hz (model %.4f)\n",
              len.size(), ml, l, 1.0 / md, 1.0 / l);
  EXPECT_NEAR(ml, l, 0.002);
  EXPECT_NEAR(1.0 / md, 1.0 / l, 0.005);
  EXPECT_NEAR(s->steps.size(), 201.06 / l, 2.0);
  // Vertical specific force swings by (l/K)⁴ per step (000 eq. 3 inverted, K = 0.45).
  double lo = 1e9, hi = -1e9;
  for (const auto& t : s->imu_truth) {
    if (t.t_s > 10.0 && t.t_s < 20.0) {
      lo = std::min(lo, t.specific_force_b.z());
      hi = std::max(hi, t.specific_force_b.z());
    }
  }
  EXPECT_NEAR(hi - lo, std::pow(l / 0.45, 4.0), 0.01);
  // A simple detector on the noisy walk finds the same number of steps: peaks of the
  // 5-sample moving average of a_z above g + A/2, at least 0.3 s apart.
  const auto& imu = s->walk.imu;
  int peaks = 0;
  double last = -1.0;
  std::vector<double> smooth(imu.size(), 0.0);
  for (size_t k = 2; k + 2 < imu.size(); ++k) {
    for (int j = -2; j <= 2; ++j) smooth[k] += imu[k + j].acc_mps2.z() / 5.0;
  }
  const double thr = 9.81 + 0.25 * std::pow(l / 0.45, 4.0);
  for (size_t k = 3; k + 3 < imu.size(); ++k) {
    if (smooth[k] > thr && smooth[k] >= smooth[k - 1] && smooth[k] > smooth[k + 1] &&
        imu[k].t_s - last > 0.3) {
      ++peaks;
      last = imu[k].t_s;
    }
  }
  EXPECT_NEAR(peaks, static_cast<double>(s->steps.size()), 3.0);
}

TEST(Simulate, ImuNoiseAndBiasMatchConfiguration) {
  auto s = SimulateScenarioDetailed("tarrio-circle", 9);
  ASSERT_TRUE(s.ok());
  std::vector<double> acc, gz;
  for (size_t k = 0; k < s->imu_truth.size(); ++k) {
    for (int i = 0; i < 3; ++i) {
      acc.push_back(s->walk.imu[k].acc_mps2[i] - s->imu_truth[k].specific_force_b[i]);
    }
    gz.push_back(s->walk.imu[k].gyro_radps.z() - s->imu_truth[k].angular_rate_b.z());
  }
  const auto [ma, sa] = Stats(acc);
  const auto [mg, sg] = Stats(gz);
  std::printf("acc noise sigma %.5f (configured 0.057575), mean %.5f; gyro z bias %.4g rad/s\n", sa,
              ma, mg);
  EXPECT_NEAR(sa, 5.7575e-2, 0.02 * 5.7575e-2);
  EXPECT_NEAR(ma, 0.0, 1e-3);
  EXPECT_NEAR(mg, DegToRad(10.0) / 3600.0, 2e-7);  // 10 °/h (000 Sec. IV), 1e-7 resolution
  EXPECT_LT(sg, 1e-6);
}

TEST(Simulate, CorreaGyroAndMagAreHeldAt15Hz) {
  auto w = SimulateScenario("correa-corridor", 3, YAML::Load("{duration_s: 30}"));
  ASSERT_TRUE(w.ok());
  int changes = 0;
  for (size_t k = 1; k < w->imu.size(); ++k) {
    if (w->imu[k].gyro_radps != w->imu[k - 1].gyro_radps) ++changes;
    EXPECT_TRUE(w->imu[k].has_mag);
  }
  EXPECT_NEAR(changes, 30.0 * 15.0, 2.0);
  EXPECT_NEAR(w->imu.size(), 30.0 * 100.0 + 1.0, 1.0);
}

// 004 Fig. 5: detection probability falls with range, few detections beyond 25 m.
TEST(Simulate, DetectionProbabilityFollowsRange) {
  auto s = SimulateScenarioDetailed("jimenez-building", 2, YAML::Load("{laps: 3}"));
  ASSERT_TRUE(s.ok());
  const double edges[] = {0, 5, 10, 15, 20, 25, 35};
  for (int b = 0; b + 1 < 7; ++b) {
    double n = 0, hits = 0, expected = 0;
    for (const auto& e : s->rss_emissions) {
      if (e.distance_m < edges[b] || e.distance_m >= edges[b + 1]) continue;
      n += 1;
      hits += e.detected;
      expected += 0.95 / (1.0 + std::exp((e.distance_m - 15.0) / 4.0));
    }
    ASSERT_GT(n, 200) << b;
    const double p = expected / n;
    std::printf("d in [%g, %g) m: detected %.3f, model %.3f (n = %.0f)\n", edges[b], edges[b + 1],
                hits / n, p, n);
    EXPECT_NEAR(hits / n, p, 4.0 * std::sqrt(p * (1 - p) / n) + 0.01);
  }
  double far = 0, all = 0;
  for (const auto& e : s->rss_emissions) {
    all += e.detected;
    far += e.detected && e.distance_m > 25.0;
  }
  EXPECT_LT(far / all, 0.10);
  // Readings are RFCode units: RSS0 = 60 at 1 m, larger is weaker, quantum 0.5.
  for (const RssSample& r : s->walk.rss) {
    EXPECT_EQ(std::fmod(r.rss * 2.0, 1.0), 0.0);
    EXPECT_LE(r.rss, 110.0);
  }
  EXPECT_EQ(s->walk.meta.radio.units, RssUnits::kRfcode);
}

TEST(Simulate, GadekeOutageSilencesTheNetwork) {
  auto w = SimulateScenario("gadeke-outage", 4, YAML::Load("{run_length_m: 400}"));
  ASSERT_TRUE(w.ok());
  const double T = w->meta.extra.at("sim.duration_s");
  // run_length_m is the waypoint polyline; rounded corners (r = 0.6 m) shorten it by ~1 %.
  EXPECT_NEAR(w->TruthDistance(), 400.0, 8.0);
  int before = 0, inside = 0, after = 0;
  for (const RssSample& s : w->rss) {
    if (s.t_s < 0.3 * T)
      ++before;
    else if (s.t_s < 0.8 * T)
      ++inside;
    else
      ++after;
  }
  EXPECT_EQ(inside, 0);
  EXPECT_GT(before, 1000);
  EXPECT_GT(after, 1000);
  EXPECT_EQ(w->meta.extra.at("sim.imu_rate_hz"), 10.0);
}

// 002 eq. 6 TOA: LOS residuals N(0, 1.5²), NLOS ones biased by +3 m on average.
TEST(Simulate, ToaRangesHaveLosNoiseAndNlosBias) {
  auto s = SimulateScenarioDetailed("prieto-laps", 6, YAML::Load("{laps: 3}"));
  ASSERT_TRUE(s.ok());
  std::vector<double> los, nlos;
  for (const auto& e : s->range_emissions) {
    (e.nlos ? nlos : los).push_back(e.value - e.distance_m);
  }
  const auto [ml, sl] = Stats(los);
  const auto [mn, sn] = Stats(nlos);
  const double share = nlos.size() / double(los.size() + nlos.size());
  std::printf("TOA LOS mean %.3f sigma %.3f; NLOS mean %.3f; NLOS share %.2f\n", ml, sl, mn, share);
  EXPECT_NEAR(ml, 0.0, 0.15);
  EXPECT_NEAR(sl, 1.5, 0.12);
  EXPECT_NEAR(mn, 3.0, 0.6);
  EXPECT_NEAR(share, 0.3, 0.15);
  EXPECT_GT(s->walk.ranges.size(), 1000u);
}

TEST(Simulate, FootWalkHasStancePhasesOfConfiguredShare) {
  auto w = SimulateScenario("jimenez-building", 8, YAML::Load("{laps: 2}"));
  ASSERT_TRUE(w.ok());
  ASSERT_EQ(w->stance_truth.size(), w->imu.size());
  // While walking steadily (after the 10 s still start), stance is ≈35 % of the time.
  double n = 0, st = 0;
  for (const auto& s : w->stance_truth) {
    if (s.t_s > 15.0 && s.t_s < 55.0) {
      n += 1;
      st += s.stance;
    }
  }
  EXPECT_NEAR(st / n, 0.35, 0.05);
  // The foot is still and level during stance: the accelerometer reads ≈ g (+ bias, noise).
  for (size_t k = 0; k < 500; ++k) EXPECT_NEAR(w->imu[k].acc_mps2.norm(), 9.81, 0.15);
}

// The foot presets' gaits (issue 21): the truth's velocity is its position's derivative (central
// difference at 1 kHz; the readings are the velocity's own differences, SampleFootImu), running
// spends a fifth of each stride flat and moves at 3 m/s, stairs put every stance on a tread (a
// whole number of rises, up to flight_rises = 12 of them) and climb and descend every leg.
TEST(Simulate, FootGaitsRunAndStairs) {
  for (const char* gait : {"walk", "run", "stairs"}) {
    SCOPED_TRACE(gait);
    auto s = SimulateScenarioDetailed(
        "jimenez-building", 3,
        YAML::Load(std::string("{gait: ") + gait + ", imu_rate_hz: 1000, duration_s: 45}"));
    ASSERT_TRUE(s.ok()) << s.status().ToString();
    const std::vector<sim::ImuTruth>& t = s->imu_truth;
    double worst = 0.0, z_min = 1e9, z_max = -1e9, off_tread = 0.0, n = 0, st = 0;
    for (size_t k = 1; k + 1 < t.size(); ++k) {
      const double dt = t[k + 1].t_s - t[k].t_s;
      const Eigen::Vector3d v = (t[k + 1].position_n - t[k - 1].position_n) / (2.0 * dt);
      worst = std::max(worst, (v - t[k].velocity_n).norm());
      z_min = std::min(z_min, t[k].position_n.z());
      z_max = std::max(z_max, t[k].position_n.z());
      if (t[k].stance) {
        const double rises = t[k].position_n.z() / 0.175;
        off_tread = std::max(off_tread, std::fabs(rises - std::round(rises)));
      }
      if (t[k].t_s > 15.0 && t[k].t_s < 45.0) {
        n += 1;
        st += t[k].stance;
      }
    }
    std::printf("%s: worst |v - dp/dt| %.2e m/s, z in [%.3f, %.3f] m, stance share %.3f\n", gait,
                worst, z_min, z_max, st / n);
    EXPECT_LT(worst, 1e-3);  // the central difference's own error at 1 kHz
    const std::string g = gait;
    EXPECT_NEAR(st / n, g == "run" ? 0.2 : 0.35, 0.05);
    if (g == "stairs") {
      EXPECT_LT(off_tread, 1e-6);
      EXPECT_NEAR(z_min, 0.0, 1e-9);
      EXPECT_NEAR(z_max, 12 * 0.175 + 0.10, 0.1);  // the top tread plus at most the lift
      EXPECT_EQ(s->walk.meta.extra.at("sim.stair_rise_m"), 0.175);
    } else {
      EXPECT_NEAR(z_min, 0.0, 1e-9);
      EXPECT_LT(z_max, g == "run" ? 0.16 : 0.11);
    }
    EXPECT_EQ(s->walk.meta.extra.at("sim.speed_mps"), g == "run"      ? 3.0
                                                      : g == "stairs" ? 0.45
                                                                      : 1.0);
  }
  auto bad = SimulateScenario("jimenez-building", 3, YAML::Load("{gait: hop}"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("walk, run, stairs"), std::string::npos)
      << bad.status().ToString();
  EXPECT_FALSE(SimulateScenario("jimenez-building", 3, YAML::Load("{speed_mps: 4}")).ok());
  EXPECT_TRUE(
      SimulateScenario("jimenez-building", 3, YAML::Load("{gait: run, speed_mps: 4}")).ok());
  EXPECT_FALSE(SimulateScenario("tarrio-circle", 3, YAML::Load("{gait: run}")).ok());  // no foot
}

TEST(Simulate, LinearGaussianIsCollinearAndHasConfiguredNoise) {
  auto w = SimulateScenario("linear-gaussian", 3, YAML::Load("{duration_s: 600}"));
  ASSERT_TRUE(w.ok());
  const Eigen::Vector2d a1 = w->anchors[0].position_m.head<2>();
  const Eigen::Vector2d a2 = w->anchors[1].position_m.head<2>();
  const Eigen::Vector2d u = (a2 - a1).normalized();
  const double h = w->meta.initial_pose->heading_rad;
  EXPECT_LT((u - Eigen::Vector2d(std::cos(h), std::sin(h))).norm(), 1e-9);
  for (const auto& t : w->truth) {
    const Eigen::Vector2d d = t.position_m.head<2>() - a1;
    EXPECT_LT(std::fabs(u.x() * d.y() - u.y() * d.x()), 1e-6);
  }
  std::vector<double> rr, od;
  for (const auto& r : w->ranges) {
    const Eigen::Vector2d a = w->anchors[w->AnchorIndex(r.anchor_id)].position_m.head<2>();
    rr.push_back(r.range_m - (TruthAt(*w, r.t_s).head<2>() - a).norm());
  }
  for (size_t k = 0; k < w->odometry.size(); ++k) {
    EXPECT_EQ(w->odometry[k].dheading_rad, 0.0);
    od.push_back(w->odometry[k].dist_m -
                 (w->truth[k + 1].position_m - w->truth[k].position_m).norm());
  }
  EXPECT_NEAR(Stats(rr).second, 0.3, 0.03);
  EXPECT_NEAR(Stats(od).second, 0.05, 0.005);
  EXPECT_NEAR(Stats(od).first, 0.0, 0.006);
}

// ------------------------------------------------------------------ two-floor-building

TEST(Simulate, TwoFloorBuildingClimbsOneStoreyByStairsAndComesBack) {
  auto s = SimulateScenarioDetailed("two-floor-building", 3);
  ASSERT_TRUE(s.ok()) << s.status().message();
  const Walk& w = s->walk;
  EXPECT_TRUE(ValidateWalk(w).ok()) << ValidateWalk(w).message();
  EXPECT_EQ(w.meta.storey_height_m, 3.5);
  ASSERT_TRUE(w.meta.initial_pose && w.meta.initial_pose->floor);
  EXPECT_EQ(*w.meta.initial_pose->floor, 0);
  EXPECT_EQ(w.meta.radio.path_loss.floor_loss_db, 15.0);
  // Anchors: 8 per floor, mounted 2.5 m above it.
  int on_floor[2] = {0, 0};
  for (const Anchor& a : w.anchors) {
    ASSERT_TRUE(a.floor.has_value());
    ASSERT_TRUE(*a.floor == 0 || *a.floor == 1);
    ++on_floor[*a.floor];
    EXPECT_EQ(a.position_m.z(), 2.5);
  }
  EXPECT_EQ(on_floor[0], 8);
  EXPECT_EQ(on_floor[1], 8);
  // Truth: the floor of every sample is its height over the storey, rounded; both floors
  // walked, floor 0 at the start and the end; heights within [0, 3.5].
  double time_on[2] = {0.0, 0.0};
  for (size_t i = 0; i < w.truth.size(); ++i) {
    const TruthSample& t = w.truth[i];
    ASSERT_TRUE(t.floor.has_value());
    EXPECT_EQ(*t.floor, static_cast<int>(std::lround(t.position_m.z() / 3.5)));
    ASSERT_GE(t.position_m.z(), -1e-9);
    ASSERT_LE(t.position_m.z(), 3.5 + 1e-9);
    if (i > 0) time_on[*t.floor] += t.t_s - w.truth[i - 1].t_s;
  }
  EXPECT_EQ(*w.truth.front().floor, 0);
  EXPECT_EQ(*w.truth.back().floor, 0);
  EXPECT_GT(time_on[1], 150.0);  // two 84-m laps at 1 m/s
  EXPECT_GT(time_on[0], 300.0);
  // Stairs: 20 rises of 0.175 m up and 20 down; each stair step moves one 0.28-m tread. A
  // step event's rise is the truth height change since the previous event.
  // Steps whose whole interval lies on a flight (the height changing at both ends):
  // 12 + 8 rises, less a flight's first and last step, each way.
  int up = 0, down = 0;
  for (const sim::StepEvent& e : s->steps) {
    const double t0 = e.t_s - e.duration_s, t1 = e.t_s;
    const double z0 = TruthAt(w, t0).z(), z1 = TruthAt(w, t1).z();
    const bool climbing = std::fabs(TruthAt(w, t0 + 0.04).z() - z0) > 1e-4 &&
                          std::fabs(z1 - TruthAt(w, t1 - 0.04).z()) > 1e-4;
    if (!climbing) continue;
    (z1 > z0 ? up : down) += 1;
    EXPECT_NEAR(std::fabs(z1 - z0), 0.175, 0.005) << "step at " << e.t_s << " s";
    EXPECT_NEAR(e.length_m, 0.28, 0.005) << "step at " << e.t_s << " s";
  }
  EXPECT_GE(up, 14);
  EXPECT_LE(up, 20);
  EXPECT_GE(down, 14);
  EXPECT_LE(down, 20);
}

// The barometer reads the standard atmosphere at the waist (1 m above the truth's floor
// height): without drift the residuals are its white noise; with a trend only, they are the
// trend (its sign in sim.baro_drift_rate_hpa_per_h); the random walk's increments have its
// variance.
TEST(Simulate, TwoFloorBuildingPressureFollowsTheTruthHeightPlusDrift) {
  auto residuals = [](const Walk& w) {
    std::vector<double> r;
    for (const PressureSample& p : w.pressure) {
      const double h = TruthAt(w, p.t_s).z() + w.meta.extra.at("sim.rx_height_offset_m");
      r.push_back(p.hpa - BarometricPressureHpa(h, 1013.25));
    }
    return r;
  };
  auto white = SimulateScenario("two-floor-building", 5,
                                YAML::Load("{baro_drift_hpa_per_h: 0, "
                                           "baro_drift_rw_hpa_per_sqrt_h: 0}"));
  ASSERT_TRUE(white.ok());
  const auto [mean, sigma] = Stats(residuals(*white));
  ASSERT_GT(white->pressure.size(), 5000u);  // 10 Hz over ≈ 9 min
  EXPECT_NEAR(white->pressure[1].t_s - white->pressure[0].t_s, 0.1, 1e-9);
  EXPECT_NEAR(mean, 0.0, 4.0 * 0.03 / std::sqrt(white->pressure.size()));
  EXPECT_NEAR(sigma, 0.03, 0.002);
  for (const char* rate : {"1.5", "4"}) {
    auto trend = SimulateScenario(
        "two-floor-building", 5,
        YAML::Load(std::string("{baro_noise_hpa: 0, baro_drift_rw_hpa_per_sqrt_h: 0, "
                               "baro_drift_hpa_per_h: ") +
                   rate + "}"));
    ASSERT_TRUE(trend.ok());
    const double signed_rate = trend->meta.extra.at("sim.baro_drift_rate_hpa_per_h");
    EXPECT_EQ(std::fabs(signed_rate), std::stod(rate));
    const std::vector<double> r = residuals(*trend);
    for (size_t i = 0; i < r.size(); i += 97) {
      EXPECT_NEAR(r[i], signed_rate * trend->pressure[i].t_s / 3600.0, 2e-4);
    }
  }
  auto rw = SimulateScenario("two-floor-building", 5,
                             YAML::Load("{baro_noise_hpa: 0, baro_drift_hpa_per_h: 0, "
                                        "baro_drift_rw_hpa_per_sqrt_h: 3}"));
  ASSERT_TRUE(rw.ok());
  const std::vector<double> r = residuals(*rw);
  std::vector<double> steps;
  for (size_t i = 10; i < r.size(); i += 10) steps.push_back(r[i] - r[i - 10]);  // 1-s steps
  EXPECT_NEAR(Stats(steps).second, 3.0 * std::sqrt(1.0 / 3600.0), 0.005);
}

// RSS across floors: the log-distance model at the 3-D distance, minus 15 dB per slab between
// anchor and receiver (1 m above the walker's floor). Every emission, also those lost to the
// sensitivity (no truncation).
TEST(Simulate, TwoFloorBuildingRssLosesTheFloorLossPerSlab) {
  auto s = SimulateScenarioDetailed("two-floor-building", 2);
  ASSERT_TRUE(s.ok());
  const Walk& w = s->walk;
  const PathLossModel model(w.meta.radio.path_loss, w.meta.radio.units);
  std::vector<double> same, other;
  for (const sim::Emission& e : s->rss_emissions) {
    const Anchor& a = w.anchors[w.AnchorIndex(e.anchor_id)];
    const Eigen::Vector3d rx = TruthAt(w, e.t_s) + Eigen::Vector3d(0, 0, 1.0);
    const Eigen::Vector3d at(a.position_m.x(), a.position_m.y(), w.AnchorHeightM(a));
    const double d = (rx - at).norm();
    ASSERT_NEAR(e.distance_m, d, 0.01);
    const int slabs =
        static_cast<int>(std::fabs(std::floor(rx.z() / 3.5) - std::floor(at.z() / 3.5)));
    (slabs == 0 ? same : other).push_back(e.value - (model.ExpectedRss(d) - 15.0 * slabs));
  }
  ASSERT_GT(same.size(), 1000u);
  ASSERT_GT(other.size(), 1000u);
  for (const auto* v : {&same, &other}) {
    const auto [mean, sigma] = Stats(*v);
    EXPECT_NEAR(mean, 0.0, 4.0 * 5.0 / std::sqrt(v->size()));
    EXPECT_NEAR(sigma, 5.0, 0.25);
  }
}

TEST(Simulate, TwoFloorBuildingKeysAreCheckedAndItsOwn) {
  EXPECT_FALSE(SimulateScenario("two-floor-building", 1, YAML::Load("{baro_drift: 1}")).ok());
  EXPECT_FALSE(
      SimulateScenario("two-floor-building", 1, YAML::Load("{storey_height_m: 1.0}")).ok());
  EXPECT_FALSE(
      SimulateScenario("two-floor-building", 1, YAML::Load("{baro_noise_hpa: -0.1}")).ok());
  EXPECT_FALSE(SimulateScenario("two-floor-building", 1,
                                YAML::Load("{storey_height_m: 3.0, anchor_mount_m: 3.0}"))
                   .ok());
  EXPECT_FALSE(SimulateScenario("tarrio-circle", 1, YAML::Load("{floor_loss_db: 10}")).ok());
  auto w = SimulateScenario("two-floor-building", 1,
                            YAML::Load("{storey_height_m: 3.0, laps: 1, num_anchors: 5}"));
  ASSERT_TRUE(w.ok()) << w.status().message();
  EXPECT_EQ(w->meta.storey_height_m, 3.0);
  EXPECT_EQ(w->anchors.size(), 5u);
  double top = 0.0;
  for (const TruthSample& t : w->truth) top = std::max(top, t.position_m.z());
  EXPECT_NEAR(top, 3.0, 1e-6);
  // Flat presets keep their planar truth, no floors and no barometer.
  auto flat = SimulateScenario("tarrio-circle", 1, YAML::Load("{duration_s: 20}"));
  ASSERT_TRUE(flat.ok());
  EXPECT_TRUE(flat->pressure.empty());
  EXPECT_FALSE(flat->has_truth_floors());
  for (const TruthSample& t : flat->truth) ASSERT_EQ(t.position_m.z(), 0.0);
}

}  // namespace
}  // namespace walkgraph
