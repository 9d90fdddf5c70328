// The YAML readers of the library's Options (internal: the layer that builds estimators; the
// front ends' readers are in stance/stance_yaml.h, ins/strides_yaml.h, pdr/pdr_yaml.h). Each reads
// a map whose keys are the Options' fields (ConfigReader: unknown keys and ill-typed values are
// errors with the line), then applies the Options' Validate().
#ifndef WALKGRAPH_SRC_CONFIG_PARSERS_H_
#define WALKGRAPH_SRC_CONFIG_PARSERS_H_

#include <map>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "config/reader.h"
#include "ins/strides_yaml.h"
#include "pdr/pdr_yaml.h"
#include "stance/stance_yaml.h"
#include "walkgraph/dead_reckoning.h"
#include "walkgraph/filters/correa.h"
#include "walkgraph/filters/front_end.h"
#include "walkgraph/filters/gadeke.h"
#include "walkgraph/filters/jimenez.h"
#include "walkgraph/filters/prieto.h"
#include "walkgraph/filters/tarrio.h"
#include "walkgraph/pdr.h"
#include "walkgraph/smoothers/ins_graph.h"
#include "walkgraph/smoothers/ins_window.h"
#include "walkgraph/smoothers/step_graph.h"
#include "walkgraph/stance.h"
#include "walkgraph/strides.h"
#include "walkgraph/zupt_ins.h"

namespace walkgraph {

// walkgraph/dead_reckoning.h
StatusOr<OdometryDeadReckoningOptions> OdometryDeadReckoningOptionsFromYaml(const YAML::Node& node);

// walkgraph/filters/correa.h
StatusOr<CorreaEkfOptions> CorreaEkfOptionsFromYaml(const YAML::Node& node,
                                                    const std::string& context);

// `scmt` and `smooth` come from the id; `id` names the estimator in messages.
StatusOr<CorreaEstimatorOptions> CorreaEstimatorOptionsFromYaml(const YAML::Node& node,
                                                                CorreaVariant variant, bool smooth,
                                                                const std::string& id);

// walkgraph/filters/front_end.h
// Keys present in `node` replace the fields of `defaults`; unknown keys are errors.
StatusOr<RadioFrontEndOptions> RadioFrontEndOptionsFromYaml(const YAML::Node& node,
                                                            const RadioFrontEndOptions& defaults,
                                                            const std::string& context);

// walkgraph/filters/gadeke.h
StatusOr<GadekeKfOptions> GadekeKfOptionsFromYaml(const YAML::Node& node,
                                                  const std::string& context);

StatusOr<GadekeEstimatorOptions> GadekeEstimatorOptionsFromYaml(const YAML::Node& node, bool smooth,
                                                                const std::string& id);

// walkgraph/filters/jimenez.h
// Every field above by its name (angles in radians), plus `stance:` (StanceOptions keys).
StatusOr<JimenezIezOptions> JimenezIezOptionsFromYaml(const YAML::Node& node,
                                                      const std::string& context, bool use_rss,
                                                      bool smooth);

// walkgraph/filters/prieto.h
// Reads the YAML keys (every field above except filter/sensors/smooth; `stance:` is a map of
// StanceOptions keys; imu_sampling: interval-average|instantaneous) over `defaults`.
StatusOr<PrietoOptions> PrietoOptionsFromYaml(const YAML::Node& node, const std::string& context,
                                              const PrietoOptions& defaults);

StatusOr<PrietoOptions> PrietoOptionsFromYaml(const YAML::Node& node, const std::string& context);

// walkgraph/filters/tarrio.h
StatusOr<TarrioKfOptions> TarrioKfOptionsFromYaml(const YAML::Node& node,
                                                  const std::string& context);

// `id` names the estimator in messages; `smooth` is set by the id (tarrio-kf-rts).
StatusOr<TarrioEstimatorOptions> TarrioEstimatorOptionsFromYaml(const YAML::Node& node,
                                                                TarrioMode mode, bool smooth,
                                                                const std::string& id);

// walkgraph/smoothers/ins_graph.h
// Keys: front_end (a map of StrideOptions keys), placement (stance|every-n) and every other
// field by its name.
StatusOr<InsGraphOptions> InsGraphOptionsFromYaml(const YAML::Node& node);
// The same over `base`: keys the map does not name keep their value there.
StatusOr<InsGraphOptions> InsGraphOptionsFromYaml(const YAML::Node& node,
                                                  const InsGraphOptions& base);

// walkgraph/smoothers/ins_window.h
// Keys: lag_s, window_update_s, window_max_iterations, window_output (absent: the given
// default), preintegration_bias, gap_hold_max_s, gap_release_yaw_sigma_rad, gap_max_iterations, and
// every InsGraphOptions key at the same level (InsGraphOptionsFromYaml); unknown keys are errors.
StatusOr<InsWindowOptions> InsWindowOptionsFromYaml(
    const YAML::Node& node, const std::string& context,
    WindowOutput default_output = WindowOutput::kLagged);

// walkgraph/smoothers/step_graph.h
// Keys: every field by its name, `pdr` a PdrOptions map; absent keys keep `defaults`.
StatusOr<StepGraphOptions> StepGraphOptionsFromYaml(const YAML::Node& node,
                                                    const std::string& context,
                                                    StepGraphOptions defaults);

// walkgraph/zupt_ins.h
// Keys: front_end (a map of StrideOptions keys), output_rate_hz, gauge_sigma_m,
// gauge_sigma_yaw_rad.
StatusOr<ZuptInsOptions> ZuptInsOptionsFromYaml(const YAML::Node& node);

// Paper estimators' configs (filters/front_end.h)
// The `pdr:` child map: PdrOptionsFromYaml of the paper's defaults (PdrOptions keys and
// values, e.g. {{"detector", "energy"}, {"forward_axis", "pca"}}) overlaid by `node`.
StatusOr<PdrOptions> PdrOptionsFromYaml(const YAML::Node& node,
                                        const std::map<std::string, std::string>& paper_defaults,
                                        const std::string& context);

// `node` without the listed top-level keys (so that a filter's own reader sees only its keys).
// Fails when `node` is neither absent, null nor a map.
StatusOr<YAML::Node> WithoutKeys(const YAML::Node& node, const std::vector<std::string>& keys,
                                 const std::string& context);
// Fails when a filter's own options `own` name one of `keys`, options its estimator id chooses
// (e.g. smooth: the "-rts" ids); `ids` names those ids in the message.
Status RefuseKeysChosenById(const YAML::Node& own, const std::vector<std::string>& keys,
                            const std::string& ids, const std::string& id);

}  // namespace walkgraph

#endif  // WALKGRAPH_SRC_CONFIG_PARSERS_H_
