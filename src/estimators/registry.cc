#include "estimators/builtin.h"
#include "util/text.h"
#include "walkgraph/estimator.h"

namespace walkgraph {

const EstimatorRegistry& EstimatorRegistry::Builtin() {
  static const EstimatorRegistry* registry = [] {
    auto* r = new EstimatorRegistry();
    // Order of tables and `walkgraph list`: dead reckoning and the papers' baselines and
    // filters (000 … 004), then walkgraph's factor-graph smoothers.
    internal::RegisterOdometryDeadReckoning(r);
    internal::RegisterZuptIns(r);
    internal::RegisterTarrio(r);
    internal::RegisterCorrea(r);
    internal::RegisterPrieto(r);
    internal::RegisterGadeke(r);
    internal::RegisterJimenezIez(r);
    internal::RegisterStepGraphSmoothers(r);
    internal::RegisterInsGraphBatch(r);
    internal::RegisterInsGraphWindow(r);
    return r;
  }();
  return *registry;
}

Status EstimatorRegistry::Register(EstimatorInfo info) {
  if (info.id.empty() || !info.factory)
    return InvalidArgument("estimator needs an id and a factory");
  if (Find(info.id) != nullptr)
    return InvalidArgument("estimator id '" + info.id + "' registered twice");
  entries_.push_back(std::move(info));
  return Status::Ok();
}

const EstimatorInfo* EstimatorRegistry::Find(const std::string& id) const {
  for (const EstimatorInfo& e : entries_) {
    if (e.id == id) return &e;
  }
  return nullptr;
}

StatusOr<std::unique_ptr<Estimator>> EstimatorRegistry::Create(const std::string& id,
                                                               const YAML::Node& config) const {
  const EstimatorInfo* info = Find(id);
  if (info == nullptr) {
    std::string ids;
    for (const EstimatorInfo& e : entries_) ids += (ids.empty() ? "" : ", ") + e.id;
    return NotFound("unknown estimator " + internal::Quoted(id) + "; known: " + ids);
  }
  return info->factory(config);
}

std::vector<std::string> EstimatorRegistry::Ids() const {
  std::vector<std::string> ids;
  for (const EstimatorInfo& e : entries_) ids.push_back(e.id);
  return ids;
}

}  // namespace walkgraph
