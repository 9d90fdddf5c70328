#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "estimators/builtin.h"
#include "util/text.h"
#include "walkgraph/estimator.h"

namespace walkgraph {

const EstimatorRegistry& EstimatorRegistry::Builtin() {
  static const EstimatorRegistry* registry = [] {
    auto* r = new EstimatorRegistry();
    // Order of tables and `walkgraph list`: dead reckoning and the papers' baselines and
    // filters (000 … 004), then walkgraph's factor-graph smoothers.
    // A failure is kept in r->status() (Register records it) and surfaces in every Create.
    for (Status (*unit)(EstimatorRegistry*) :
         {internal::RegisterOdometryDeadReckoning, internal::RegisterZuptIns,
          internal::RegisterTarrio, internal::RegisterCorrea, internal::RegisterPrieto,
          internal::RegisterGadeke, internal::RegisterJimenezIez,
          internal::RegisterStepGraphSmoothers, internal::RegisterInsGraphBatch,
          internal::RegisterInsGraphWindow}) {
      if (!unit(r).ok()) break;
    }
    return r;
  }();
  return *registry;
}

Status EstimatorRegistry::Register(EstimatorInfo info) {
  Status status = Status::Ok();
  if (info.id.empty() || !info.factory) {
    status = InvalidArgument("estimator needs an id and a factory");
  } else if (Find(info.id) != nullptr) {
    status = InvalidArgument("estimator id '" + info.id + "' registered twice");
  }
  if (!status.ok()) {
    if (status_.ok()) status_ = status;
    return status;
  }
  entries_.push_back(std::move(info));
  return Status::Ok();
}

const EstimatorInfo* EstimatorRegistry::Find(const std::string& id) const {
  for (const EstimatorInfo& e : entries_) {
    if (e.id == id) return &e;
  }
  return nullptr;
}

namespace {

Status RegistryBroken(const Status& registration) {
  return Status(registration.code(),
                "estimator registry: a registration failed: " + registration.message());
}

// {a: {b: value}} for the key "a.b"; an unset number (NaN, "the walk's value") as null, which
// keeps the default.
YAML::Node ConfigWith(const OptionDefault& d) {
  YAML::Node value;
  std::visit([&](const auto& v) { value = v; }, d.value);
  if (const double* x = std::get_if<double>(&d.value); x && std::isnan(*x)) value = YAML::Node();
  std::string key = d.key;
  std::vector<std::string> path;
  for (size_t dot; (dot = key.find('.')) != std::string::npos; key = key.substr(dot + 1)) {
    path.push_back(key.substr(0, dot));
  }
  YAML::Node node(YAML::NodeType::Map);
  node[key] = value;
  for (auto it = path.rbegin(); it != path.rend(); ++it) {
    YAML::Node parent(YAML::NodeType::Map);
    parent[*it] = node;
    node = parent;
  }
  return node;
}

// An estimator that needs every anchor's position, on walks with anchors of unknown position:
// runs without them and their readings, and says how many it left out.
class SurveyedAnchorsOnly : public Estimator {
 public:
  explicit SurveyedAnchorsOnly(std::unique_ptr<Estimator> inner) : inner_(std::move(inner)) {}
  Status CheckApplicable(const Walk& walk) const override {
    if (!walk.has_unknown_anchors()) return inner_->CheckApplicable(walk);
    return inner_->CheckApplicable(WithoutUnknownAnchors(walk));
  }
  StatusOr<EstimateResult> Run(const Walk& walk) const override {
    if (!walk.has_unknown_anchors()) return inner_->Run(walk);
    UnknownAnchorsDropped dropped;
    const Walk known = WithoutUnknownAnchors(walk, &dropped);
    WG_ASSIGN_OR_RETURN(EstimateResult result, inner_->Run(known));
    result.diagnostics["unknown_anchors_ignored"] = dropped.anchors;
    result.diagnostics["unknown_anchor_readings_ignored"] =
        dropped.rss_readings + dropped.range_readings;
    return result;
  }

 private:
  std::unique_ptr<Estimator> inner_;
};

}  // namespace

StatusOr<std::vector<OptionDefault>> EstimatorRegistry::OptionDefaults(
    const std::string& id) const {
  if (!status_.ok()) return RegistryBroken(status_);
  WG_ASSIGN_OR_RETURN(std::vector<OptionDefault> read,
                      RecordOptionDefaults([&] { return Create(id).status(); }));
  // What the parsers read is a superset of what a config may set (a key the id fixes, a
  // nested reader of a part this variant does not use): keep the keys the estimator accepts.
  std::vector<OptionDefault> accepted;
  for (OptionDefault& d : read) {
    if (Create(id, ConfigWith(d)).ok()) accepted.push_back(std::move(d));
  }
  return accepted;
}

StatusOr<std::unique_ptr<Estimator>> EstimatorRegistry::Create(const std::string& id,
                                                               const Config& config) const {
  if (!status_.ok()) return RegistryBroken(status_);
  const EstimatorInfo* info = Find(id);
  if (info == nullptr) {
    std::string ids;
    for (const EstimatorInfo& e : entries_) ids += (ids.empty() ? "" : ", ") + e.id;
    return NotFound("unknown estimator " + internal::Quoted(id) + "; known: " + ids);
  }
  WG_ASSIGN_OR_RETURN(std::unique_ptr<Estimator> estimator, info->factory(config));
  if (info->estimates_unknown_anchors) return estimator;
  return std::unique_ptr<Estimator>(std::make_unique<SurveyedAnchorsOnly>(std::move(estimator)));
}

std::vector<std::string> EstimatorRegistry::Ids() const {
  std::vector<std::string> ids;
  for (const EstimatorInfo& e : entries_) ids.push_back(e.id);
  return ids;
}

}  // namespace walkgraph
