// walkgraph validate, convert, fit-path-loss, smooth, simulate, stance-search, list.
#include "cli.h"

namespace walkgraph_cli {

int RunValidate(const std::string& walk_dir) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  std::cout << walk_dir << ": OK (" << walk->anchors.size() << " anchors, " << walk->imu.size()
            << " IMU, " << walk->rss.size() << " RSS, " << walk->ranges.size() << " range, "
            << walk->odometry.size() << " odometry, " << walk->truth.size() << " truth samples"
            << (walk->waypoints.empty()
                    ? ""
                    : ", " + std::to_string(walk->waypoints.size()) + " waypoints")
            << "; " << walk->EndTime() - walk->StartTime() << " s)\n";
  return 0;
}

int RunConvert(const std::string& format, const std::vector<std::string>& sources,
               const walkgraph::ConvertOptions& options, const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, sources); !s.ok()) return Fail(s);
  std::vector<std::string> warnings;
  auto walk = walkgraph::Convert(format, sources, options, &warnings);
  if (!walk.ok()) return Fail(walk.status());
  for (const std::string& w : warnings) std::cerr << "walkgraph: warning: " << w << "\n";
  const Status s = walkgraph::WriteWalk(*walk, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << "\n";
  return 0;
}

// Fits RSS = A − 10·η·log10(d/d0) to a walk's RSS readings against its truth (positions
// linearly interpolated between truth samples; readings outside the truth's span are skipped;
// the distance is 3-D when the truth has a height, else horizontal to the anchor's x-y with the
// anchor's height against 0). With `floors` (--floors; truth and anchors with floors): the
// receiver at its truth floor's height, the anchor at Walk::AnchorHeightM, and the floor loss
// per floor crossed fitted with A and η (FitPathLoss) — the model of the step-graph estimators
// when floor_loss_db > 0, not of the planar filters (their A, η come from the plain fit). Prints a
// `radio:` block for walk.yaml (global fit) and the fit per anchor as comments. Meant to calibrate
// one walk's path loss for use on a different walk.
int RunFitPathLoss(const std::string& walk_dir, bool floors) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  const auto& truth = walk->truth;
  if (truth.size() < 2) return Fail(walkgraph::FailedPrecondition("fit-path-loss: no truth"));
  std::vector<walkgraph::PathLossObservation> obs;
  for (const walkgraph::RssSample& r : walk->rss) {
    const auto it =
        std::lower_bound(truth.begin(), truth.end(), r.t_s,
                         [](const walkgraph::TruthSample& t, double x) { return t.t_s < x; });
    if (it == truth.end() || it == truth.begin() || r.t_s < truth.front().t_s) continue;
    const auto& b = *it;
    const auto& a = *(it - 1);
    const double w = b.t_s > a.t_s ? (r.t_s - a.t_s) / (b.t_s - a.t_s) : 0.0;
    Eigen::Vector3d p = (1 - w) * a.position_m + w * b.position_m;
    if (!a.has_z || !b.has_z) p.z() = 0.0;
    const walkgraph::Anchor* anchor = nullptr;
    for (const auto& an : walk->anchors) {
      if (an.id == r.anchor_id) anchor = &an;
    }
    if (anchor == nullptr) continue;
    Eigen::Vector3d anchor_m = anchor->position_m;
    const std::optional<int> floor = w < 0.5 ? a.floor : b.floor;  // floors do not interpolate
    int crossed = 0;
    if (floors && floor && anchor->floor) {
      p.z() = *floor * walk->meta.storey_height_m;
      anchor_m.z() = walk->AnchorHeightM(*anchor);
      crossed = std::abs(*floor - *anchor->floor);
    }
    obs.push_back({r.anchor_id, (anchor_m - p).norm(), r.rss, crossed});
  }
  const auto units = walk->meta.radio.units;
  const double d0 = walk->meta.radio.path_loss.d0_m;
  auto fit = walkgraph::FitPathLoss(obs, units, d0);
  if (!fit.ok()) return Fail(fit.status());
  // The printed block goes into a walk.yaml: a fit that walk.yaml would refuse is an error.
  std::string absurd = walkgraph::internal::CheckPathLoss(fit->params, units, {});
  if (absurd.empty() && !(fit->params.floor_loss_db >= 0.0 && fit->params.floor_loss_db <= 100.0)) {
    absurd = "floor_loss_db " + walkgraph::internal::Num(fit->params.floor_loss_db) +
             " outside [0, 100] dB";
  }
  if (!absurd.empty()) {
    return Fail(walkgraph::FailedPrecondition(
        "fit-path-loss " + walk_dir + ": the fit over " + std::to_string(fit->num_observations) +
        " readings is not a usable path-loss model: " + absurd +
        ". Expected RSS that falls with the distance to the anchors: check anchors.csv's "
        "positions and ids, radio.units, and that the truth is in the anchors' frame"));
  }
  std::printf("# fit-path-loss %s: %d readings inside the truth's span\n", walk_dir.c_str(),
              fit->num_observations);
  auto per = walkgraph::FitPathLossPerAnchor(obs, units, d0);
  if (per.ok()) {
    for (const auto& f : *per) {
      std::printf("# anchor %d: A %.2f eta %.3f sigma %.2f (n = %d)\n", f.anchor_id, f.params.A_dbm,
                  f.params.eta, f.params.sigma_db, f.num_observations);
    }
  }
  std::printf("A_dbm: %.3f\neta: %.4f\nsigma_db: %.3f\nfloor_loss_db: %.3f\ncalibrated: true\n",
              fit->params.A_dbm, fit->params.eta, fit->params.sigma_db, fit->params.floor_loss_db);
  return 0;
}

namespace {

// smooth --config takes compare's shape, {id: {option: value}} (the section of --estimator
// used), or one estimator's options alone, {option: value}: a map whose keys are all estimator
// ids is the former.
walkgraph::StatusOr<YAML::Node> SmoothOptions(const YAML::Node& config, const std::string& id,
                                              const std::string& path) {
  if (!config.IsMap() || config.size() == 0) return config;
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const auto& kv : config) {
    if (!kv.first.IsScalar() || registry.Find(kv.first.Scalar()) == nullptr) return config;
  }
  if (!config[id]) {
    return walkgraph::InvalidArgument(
        path + ":" + std::to_string(config.Mark().line + 1) +
        ": a file of sections by estimator id (compare's shape) without a section for '" + id +
        "'");
  }
  return config[id];
}

}  // namespace

int RunSmooth(const std::string& walk_dir, const std::string& id, const std::string& config_path,
              const std::string& out, const std::string& ipin_out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFile, {walk_dir, config_path, g_radio_map});
      !s.ok()) {
    return Fail(s);
  }
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  auto file = LoadConfig(config_path);
  if (!file.ok()) return Fail(file.status());
  auto config = SmoothOptions(*file, id, config_path);
  if (!config.ok()) return Fail(config.status());
  auto est = walkgraph::EstimatorRegistry::Builtin().Create(id, *config);
  if (!est.ok()) return Fail(InConfig(config_path, est.status()));
  const Status applicable = (*est)->CheckApplicable(*walk);
  if (!applicable.ok()) return Fail(applicable);
  auto result = (*est)->Run(*walk);
  if (!result.ok()) return Fail(result.status());
  const Status s = walkgraph::WriteTumTrajectory(result->trajectory, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << " (" << result->trajectory.size() << " poses)\n";
  if (!ipin_out.empty()) {
    const Status si = walkgraph::WriteIpinSubmission(*walk, result->trajectory, ipin_out, g_output);
    if (!si.ok()) return Fail(si);
    std::cout << "wrote " << ipin_out << " (IPIN submission, 2 Hz from t = 0)\n";
  }
  return 0;
}

namespace {

// survey.csv: what the map's anchors.csv cannot hold, per mapped anchor.
bool WriteSurveyDetails(const walkgraph::RadioMap& map, std::ostream& o) {
  using walkgraph::internal::Num;
  o << "id,x_m,y_m,cov_xx,cov_xy,cov_yy,walks,readings,disagreement\n";
  for (const walkgraph::SurveyedAnchor& a : map.details) {
    o << a.id << ',' << Num(a.position_m.x(), 10) << ',' << Num(a.position_m.y(), 10) << ','
      << Num(a.covariance(0, 0)) << ',' << Num(a.covariance(0, 1)) << ',' << Num(a.covariance(1, 1))
      << ',' << a.walks << ',' << a.readings << ',' << Num(a.disagreement) << '\n';
  }
  return static_cast<bool>(o);
}

}  // namespace

int RunSurvey(const std::vector<std::string>& walk_dirs, const walkgraph::SurveyOptions& options,
              const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, walk_dirs); !s.ok()) {
    return Fail(s);
  }
  std::vector<walkgraph::Walk> walks;
  for (const std::string& dir : walk_dirs) {
    auto walk = ReadWalk(dir);
    if (!walk.ok()) return Fail(walk.status());
    walks.push_back(std::move(*walk));
  }
  auto map = walkgraph::SurveyRadioMap(walks, options);
  if (!map.ok()) return Fail(map.status());
  const Status s = walkgraph::WriteOutputFolder(out, g_output, [&](const std::string& tmp) {
    WG_RETURN_IF_ERROR(walkgraph::WriteFileInOutput(tmp + "/anchors.csv", [&](std::ostream& o) {
      walkgraph::FormatAnchorsCsv(map->anchors, o);
      return static_cast<bool>(o);
    }));
    return walkgraph::WriteFileInOutput(
        tmp + "/survey.csv", [&](std::ostream& o) { return WriteSurveyDetails(*map, o); });
  });
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << ": " << map->details.size() << " anchors placed from "
            << walks.size() << " walks (" << map->anchors.size() - map->details.size()
            << " surveyed kept; " << map->unobservable << " walk estimates unobservable); "
            << (options.pool_disagreement
                    ? "variance factor " + walkgraph::internal::Num(map->variance_factor) +
                          " (the walks' disagreement: every anchor's covariance at least that "
                          "times its solve's)"
                    : std::string("variance factor off (--no-pool-disagreement)"))
            << "\n";
  return 0;
}

int RunSimulate(const std::string& scenario, uint64_t seed, const std::string& config_path,
                const std::string& out) {
  if (Status s = Preflight(out, walkgraph::OutputKind::kFolder, {config_path}); !s.ok()) {
    return Fail(s);
  }
  auto config = LoadConfig(config_path);
  if (!config.ok()) return Fail(config.status());
  auto walk = walkgraph::SimulateScenario(scenario, seed, *config);
  if (!walk.ok()) {
    const bool about_config = walk.status().code() == walkgraph::StatusCode::kInvalidArgument;
    return Fail(about_config ? InConfig(config_path, walk.status()) : walk.status());
  }
  const Status s = walkgraph::WriteWalk(*walk, out, g_output);
  if (!s.ok()) return Fail(s);
  std::cout << "wrote " << out << " (" << walk->imu.size() << " IMU, " << walk->rss.size()
            << " RSS, " << walk->ranges.size() << " range, " << walk->odometry.size()
            << " odometry samples; " << walk->EndTime() - walk->StartTime() << " s)\n";
  return 0;
}

int RunStanceSearch(const std::string& walk_dir, const std::string& detector,
                    const std::string& config_path, const std::vector<double>& thresholds) {
  auto walk = ReadWalk(walk_dir);
  if (!walk.ok()) return Fail(walk.status());
  auto config = LoadConfig(config_path);
  if (!config.ok()) return Fail(config.status());
  auto options = walkgraph::StanceOptionsFromYaml(*config);
  if (!options.ok()) return Fail(InConfig(config_path, options.status()));
  auto type = walkgraph::StanceDetectorFromString(detector);
  if (!type.ok()) return Fail(type.status());
  options->detector = *type;
  auto scores = walkgraph::StanceThresholdSearch(*walk, *options, thresholds);
  if (!scores.ok()) return Fail(scores.status());
  std::printf("# %s, detector %s, window %d: stance precision/recall vs stance_truth\n",
              walk_dir.c_str(), detector.c_str(), options->window);
  std::printf("%12s %9s %9s %9s %9s %9s %9s\n", "threshold", "precision", "recall", "F1", "TP",
              "FP", "FN");
  for (const auto& s : *scores) {
    const double p = s.precision(), r = s.recall();
    const double f1 = p + r > 0 ? 2 * p * r / (p + r) : 0.0;
    std::printf("%12.5g %9.4f %9.4f %9.4f %9ld %9ld %9ld\n", s.threshold, p, r, f1, s.true_positive,
                s.false_positive, s.false_negative);
  }
  return 0;
}

namespace {

// An option's default as the YAML reader holds it.
std::string DefaultText(const walkgraph::OptionDefault& d) {
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          return v ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::string>) {
          return "'" + v + "'";
        } else {
          std::ostringstream s;
          s << v;
          return s.str();
        }
      },
      d.value);
}

// walkgraph list ID: the estimator's description and every option it accepts with its default
// (the keys the YAML reader records, so the list cannot drift from what a config may set).
int RunListEstimator(const std::string& id) {
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  const walkgraph::EstimatorInfo* info = registry.Find(id);
  if (info == nullptr) return Fail(registry.Create(id).status());
  auto defaults = registry.OptionDefaults(id);
  if (!defaults.ok()) return Fail(defaults.status());
  std::cout << id << "  — " << info->description << "\n";
  if (defaults->empty()) {
    std::cout << "options: none\n";
    return 0;
  }
  std::cout << "options (YAML keys of --config): default, unit (from the key's suffix) or the "
               "values a string option allows, what it does:\n";
  auto extra_of = [](const walkgraph::OptionDefault& d) {
    std::string allowed;
    for (const std::string& a : d.allowed) allowed += (allowed.empty() ? "" : "|") + a;
    const std::string unit = walkgraph::OptionUnit(d.key);
    return !unit.empty() ? unit : allowed.empty() ? "" : "one of " + allowed;
  };
  size_t width = 0, value_width = 0, extra_width = 0;
  for (const auto& d : *defaults) {
    width = std::max(width, d.key.size());
    value_width = std::max(value_width, DefaultText(d).size());
    if (extra_of(d).size() <= 12) extra_width = std::max(extra_width, extra_of(d).size());
  }
  auto pad = [](const std::string& s, size_t w) {
    return s + std::string(std::max(w, s.size()) - s.size() + 2, ' ');
  };
  for (const auto& d : *defaults) {
    std::string line = "  " + pad(d.key, width) + pad(DefaultText(d), value_width) +
                       pad(extra_of(d), extra_width) + d.doc;
    while (!line.empty() && line.back() == ' ') line.pop_back();
    std::cout << line << "\n";
  }
  return 0;
}

}  // namespace

int RunList(const std::string& id) {
  if (!id.empty()) return RunListEstimator(id);
  std::cout
      << "estimators (walkgraph list ID: its options with defaults, units and allowed values):\n";
  const auto& registry = walkgraph::EstimatorRegistry::Builtin();
  for (const std::string& e : registry.Ids()) {
    std::cout << "  " << e << "  — " << registry.Find(e)->description << "\n";
  }
  std::cout << "formats (walkgraph convert FORMAT SRC...):\n";
  for (const auto& c : walkgraph::Converters()) {
    std::cout << "  " << c.format << "  — " << c.description << "\n";
  }
  std::cout << "scenarios (walkgraph simulate --scenario NAME):\n";
  for (const auto& sc : walkgraph::Scenarios()) {
    std::cout << "  " << sc.name << "  — " << sc.description << "\n";
  }
  return 0;
}

}  // namespace walkgraph_cli
