// The estimator registry: a failed registration is returned and kept, and a registry holding one
// refuses to create estimators; the built-in registry registers every unit without failure.
#include <memory>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "walkgraph/estimator.h"

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

class Constant : public Estimator {
 public:
  Status CheckApplicable(const Walk&) const override { return Status::Ok(); }
  StatusOr<EstimateResult> Run(const Walk&) const override { return EstimateResult(); }
};

EstimatorFactory ConstantFactory() {
  return [](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
    return std::unique_ptr<Estimator>(new Constant());
  };
}

TEST(EstimatorRegistry, BuiltinRegistersEveryUnitWithoutFailure) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  EXPECT_TRUE(r.status().ok()) << r.status().message();
  for (const char* id : {"odometry-dr", "zupt-ins", "tarrio-kf", "correa-ekf", "prieto-ekf",
                         "gadeke-kf", "jimenez-iez", "fg-batch", "fg-ins-batch", "fg-ins-window"}) {
    EXPECT_TRUE(r.Create(id).ok()) << id;
  }
}

// `walkgraph list ID` and docs/estimators.md show each option's doc line from its Read call: a
// builtin option without one is a hole in the documentation.
TEST(EstimatorRegistry, EveryBuiltinOptionHasAOneLineDoc) {
  const EstimatorRegistry& r = EstimatorRegistry::Builtin();
  int options = 0;
  for (const std::string& id : r.Ids()) {
    auto defaults = r.OptionDefaults(id);
    ASSERT_TRUE(defaults.ok()) << id << ": " << defaults.status().message();
    for (const OptionDefault& o : *defaults) {
      ++options;
      EXPECT_FALSE(o.doc.empty()) << id << ": option " << o.key << " has no doc";
      EXPECT_EQ(o.doc.find('\n'), std::string::npos)
          << id << ": " << o.key << " doc is not one line";
    }
  }
  EXPECT_GT(options, 1000);  // 2,532 over 33 ids when written: the listing is not empty
}

TEST(EstimatorRegistry, DuplicateIdIsReturnedKeptAndRefusesCreate) {
  EstimatorRegistry r;
  ASSERT_TRUE(r.Register({"a", "first", ConstantFactory()}).ok());
  EXPECT_TRUE(r.Create("a").ok());
  const Status dup = r.Register({"a", "second", ConstantFactory()});
  ASSERT_FALSE(dup.ok());
  EXPECT_THAT(dup.message(), HasSubstr("'a' registered twice"));
  EXPECT_FALSE(r.status().ok());
  EXPECT_EQ(r.Ids().size(), 1u);
  auto created = r.Create("a");
  ASSERT_FALSE(created.ok());
  EXPECT_THAT(created.status().message(), HasSubstr("registered twice"));
  EXPECT_FALSE(r.OptionDefaults("a").ok());
}

TEST(EstimatorRegistry, EmptyIdOrMissingFactoryIsAFailure) {
  EstimatorRegistry r;
  EXPECT_FALSE(r.Register({"", "no id", ConstantFactory()}).ok());
  EXPECT_FALSE(r.status().ok());
  EstimatorRegistry s;
  EXPECT_FALSE(s.Register({"b", "no factory", nullptr}).ok());
  EXPECT_FALSE(s.Create("b").ok());
}

}  // namespace
}  // namespace walkgraph
