#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/config.h"

namespace walkgraph {
namespace {

using ::testing::HasSubstr;

TEST(ConfigReader, ReadsKnownKeysAndKeepsDefaults) {
  const YAML::Node node = YAML::Load("sigma: 2.5\nn: 3\nrobust: true\nname: huber\n");
  double sigma = 1.0, absent = 7.0;
  int n = 0;
  bool robust = false;
  std::string name;
  ConfigReader r(node, "test");
  r.Read("sigma", &sigma);
  r.Read("n", &n);
  r.Read("robust", &robust);
  r.Read("name", &name);
  r.Read("absent", &absent);
  ASSERT_TRUE(r.Finish().ok()) << r.Finish().message();
  EXPECT_EQ(sigma, 2.5);
  EXPECT_EQ(n, 3);
  EXPECT_TRUE(robust);
  EXPECT_EQ(name, "huber");
  EXPECT_EQ(absent, 7.0);
}

TEST(ConfigReader, RejectsUnknownKeyWithLine) {
  const YAML::Node node = YAML::Load("sigma: 2.5\nsigmma: 3\n");
  double sigma = 0;
  ConfigReader r(node, "tarrio-kf");
  r.Read("sigma", &sigma);
  const Status s = r.Finish();
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.message(), HasSubstr("tarrio-kf (line 2): unknown option 'sigmma'"));
}

TEST(ConfigReader, RejectsWrongType) {
  const YAML::Node node = YAML::Load("sigma: [1, 2]\n");
  double sigma = 0;
  ConfigReader r(node, "x");
  r.Read("sigma", &sigma);
  ASSERT_FALSE(r.Finish().ok());
  EXPECT_THAT(r.Finish().message(), HasSubstr("'sigma' must be a finite decimal number"));
}

TEST(ConfigReader, EmptyNodeIsFine) {
  ConfigReader r(YAML::Node(), "x");
  double v = 3;
  r.Read("v", &v);
  EXPECT_TRUE(r.Finish().ok());
  EXPECT_EQ(v, 3);
}

}  // namespace
}  // namespace walkgraph
