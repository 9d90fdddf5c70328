#include <gmock/gmock.h>
#include <cmath>
#include <set>
#include <variant>

#include <gtest/gtest.h>

#include "config/reader.h"
#include "walkgraph/config.h"
#include "walkgraph/estimator.h"
#include "walkgraph/pdr.h"
#include "walkgraph/smoothers/ins_graph.h"
#include "walkgraph/smoothers/step_graph.h"

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

// A string option with a fixed set of values refuses others with its line and the list, and
// records the list for `walkgraph list ID`; an enum option reads its names from its table.
TEST(ConfigReader, StringOptionsWithAllowedValues) {
  std::string loss = "cauchy";
  ConfigReader ok(YAML::Load("loss: huber\n"), "test");
  ok.Read("loss", &loss, {"none", "huber", "cauchy"});
  ASSERT_TRUE(ok.Finish().ok());
  EXPECT_EQ(loss, "huber");
  ConfigReader bad(YAML::Load("a: 1\nloss: hubr\n"), "test");
  double a = 0.0;
  bad.Read("a", &a);
  bad.Read("loss", &loss, {"none", "huber", "cauchy"});
  EXPECT_THAT(
      bad.Finish().message(),
      HasSubstr("test (line 2): option 'loss' must be one of none, huber, cauchy, found 'hubr'"));
  enum class Mode { kA, kB };
  const std::vector<std::pair<std::string, Mode>> names = {{"a", Mode::kA}, {"b", Mode::kB}};
  Mode mode = Mode::kA;
  ConfigReader e(YAML::Load("mode: b\n"), "test");
  e.ReadEnum("mode", &mode, names);
  ASSERT_TRUE(e.Finish().ok());
  EXPECT_EQ(mode, Mode::kB);
  auto recorded = RecordOptionDefaults([&] {
    Mode m = Mode::kB;
    std::string s = "x";
    ConfigReader r(YAML::Node(), "test");
    r.ReadEnum("mode", &m, names);
    r.Read("s", &s, {"x", "y"});
    return r.Finish();
  });
  ASSERT_TRUE(recorded.ok());
  ASSERT_EQ(recorded->size(), 2u);
  EXPECT_EQ(std::get<std::string>((*recorded)[0].value), "b");  // the default's name
  EXPECT_EQ((*recorded)[0].allowed, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ((*recorded)[1].allowed, (std::vector<std::string>{"x", "y"}));
}

// One names table per enum: ToString, FromString and Validate's check read it.
TEST(EnumNames, ToStringFromStringAndValidateShareOneTable) {
  EXPECT_STREQ(ToString(LossKind::kSoftL1), "soft-l1");
  EXPECT_EQ(*LossKindFromString("tukey"), LossKind::kTukey);
  // Spellings are exact: "Huber" is refused, not silently no loss (issue 18).
  const StatusOr<LossKind> huber = LossKindFromString("Huber");
  ASSERT_FALSE(huber.ok());
  EXPECT_EQ(huber.status().message(),
            "loss must be one of none, huber, cauchy, soft-l1, arctan, tukey, not 'Huber'");
  for (const auto& [name, value] : PathLossModeNames()) {
    EXPECT_EQ(*PathLossModeFromString(ToString(value)), value) << name;
  }
  EXPECT_TRUE(CheckEnumOption(WindowOutputNames(), WindowOutput::kOnline, "out", "t").ok());
  EXPECT_EQ(
      CheckEnumOption(WindowOutputNames(), static_cast<WindowOutput>(7), "out", "t").message(),
      "t: out must be one of lagged, online, not the value 7");
}

// An enum option set from C++ to a value outside its table is refused by Validate (Run).
TEST(EnumNames, ValidateRefusesAnOutOfTableValue) {
  StepGraphOptions step;
  EXPECT_TRUE(step.Validate().ok());
  step.rss_loss = static_cast<LossKind>(42);
  EXPECT_THAT(step.Validate().message(), HasSubstr("rss_loss must be one of"));
  InsGraphOptions ins;
  EXPECT_TRUE(ins.Validate().ok());
  ins.path_loss = PathLossMode::kPerAnchor;  // not one of fg-ins-batch's modes
  EXPECT_THAT(ins.Validate().message(), HasSubstr("path_loss must be one of"));
  PdrOptions pdr;
  pdr.energy_lockout_keep = static_cast<EnergyLockoutKeep>(9);
  EXPECT_FALSE(pdr.Validate().ok());
}

// The estimators' string options refuse an unknown value from YAML, naming the allowed ones.
TEST(EnumNames, EstimatorsRefuseUnknownValuesNamingTheAllowedOnes) {
  const auto& reg = EstimatorRegistry::Builtin();
  for (const auto& [id, yaml] : std::vector<std::pair<const char*, const char*>>{
           {"tarrio-kf", "{prediction: magic}"},
           {"pdr-only", "{start: middle}"},
           {"pdr-only", "{pdr: {energy_lockout_keep: last}}"},
           {"jimenez-iez", "{stance_source: oracle}"},
           {"fg-ins-window", "{preintegration_bias: x}"},
           {"fg-batch", "{path_loss: magic}"},
           {"fg-ins-batch", "{rss_loss: magic}"}}) {
    auto est = reg.Create(id, YAML::Load(yaml));
    ASSERT_FALSE(est.ok()) << id << " " << yaml;
    EXPECT_THAT(est.status().message(), HasSubstr("must be one of")) << id << " " << yaml;
  }
}

TEST(OptionUnit, FromTheKeysSuffix) {
  EXPECT_EQ(OptionUnit("lag_s"), "s");
  EXPECT_EQ(OptionUnit("sigma_acc_mps2"), "m/s²");
  EXPECT_EQ(OptionUnit("pdr.stride.gyro_noise_radps"), "rad/s");
  EXPECT_EQ(OptionUnit("acc_bias_rw_mps2_sqrts"), "m/s²/√s");
  EXPECT_EQ(OptionUnit("A_prior_sigma_db"), "dB");
  EXPECT_EQ(OptionUnit("rss_alpha_dbm"), "dBm");
  EXPECT_EQ(OptionUnit("max_iterations"), "");
  EXPECT_EQ(OptionUnit("eta"), "");
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

// Numbers are decimal and finite, as in the walk format's CSV files.
TEST(ConfigReader, ReadsOnlyFiniteDecimalNumbers) {
  for (const char* bad : {"0x5", "0x1p3", ".nan", ".inf", "-.inf", "1e999", "1_000", "five"}) {
    ConfigReader r(YAML::Load(std::string("v: ") + bad), "x");
    double v = 0;
    r.Read("v", &v);
    EXPECT_FALSE(r.Finish().ok()) << bad;
  }
  ConfigReader r(YAML::Load("a: 1e-320\nb: -2.5e3\nc: .5\nn: +7"), "x");
  double a = 0, b = 0, c = 0;
  int n = 0;
  r.Read("a", &a);
  r.Read("b", &b);
  r.Read("c", &c);
  r.Read("n", &n);
  ASSERT_TRUE(r.Finish().ok()) << r.Finish().message();
  EXPECT_GT(a, 0.0);  // a subnormal number is finite
  EXPECT_EQ(b, -2500.0);
  EXPECT_EQ(c, 0.5);
  EXPECT_EQ(n, 7);
  ConfigReader big(YAML::Load("n: 99999999999999999999999999999999999999"), "x");
  big.Read("n", &n);
  EXPECT_THAT(big.Finish().message(), HasSubstr("... (38 bytes)"));  // not echoed whole
}

// A seed: any uint64_t, nothing negative, nothing larger.
TEST(ConfigReader, ReadsUnsigned64BitIntegers) {
  ConfigReader r(YAML::Load("a: 18446744073709551615\nb: +7\n"), "x");
  uint64_t a = 0, b = 0, absent = 5;
  r.Read("a", &a);
  r.Read("b", &b);
  r.Read("absent", &absent);
  ASSERT_TRUE(r.Finish().ok()) << r.Finish().message();
  EXPECT_EQ(a, 18446744073709551615u);
  EXPECT_EQ(b, 7u);
  EXPECT_EQ(absent, 5u);
  for (const char* bad : {"-1", "18446744073709551616", "1.5", "0x10"}) {
    ConfigReader rb(YAML::Load(std::string("seed: ") + bad), "x");
    uint64_t seed = 0;
    rb.Read("seed", &seed);
    EXPECT_THAT(rb.Finish().message(),
                HasSubstr("x (line 1): option 'seed' must be a decimal integer in [0, "
                          "18446744073709551615], found '" +
                          std::string(bad) + "'"));
  }
}

// A list of plain values, each as written; anything else is a type error at its line.
TEST(ConfigReader, ReadsListsOfPlainValues) {
  ConfigReader r(YAML::Load("ids: [a, 1.50, 'b c']\nempty: []\n"), "x");
  std::vector<std::string> ids, empty = {"default"}, absent = {"kept"};
  r.Read("ids", &ids);
  r.Read("empty", &empty);
  r.Read("absent", &absent);
  ASSERT_TRUE(r.Finish().ok()) << r.Finish().message();
  EXPECT_EQ(ids, (std::vector<std::string>{"a", "1.50", "b c"}));
  EXPECT_TRUE(empty.empty());
  EXPECT_EQ(absent, std::vector<std::string>{"kept"});
  for (const char* bad : {"ids: a", "ids: [a, [b]]", "ids: {a: 1}"}) {
    ConfigReader rb(YAML::Load(std::string("x: 1\n") + bad), "x");
    std::vector<std::string> v = {"kept"};
    rb.Read("ids", &v);
    EXPECT_THAT(rb.Finish().message(),
                HasSubstr("x (line 2): option 'ids' must be a list of plain values"))
        << bad;
    EXPECT_EQ(v, std::vector<std::string>{"kept"}) << bad;
  }
  auto recorded = RecordOptionDefaults([] {
    std::vector<std::string> v = {"a", "b"};
    uint64_t seed = 9;
    ConfigReader rr(YAML::Node(), "x");
    rr.Read("v", &v);
    rr.Read("seed", &seed);
    return rr.Finish();
  });
  ASSERT_TRUE(recorded.ok());
  ASSERT_EQ(recorded->size(), 2u);
  EXPECT_EQ(std::get<std::string>((*recorded)[0].value), "a, b");
  EXPECT_EQ(std::get<std::string>((*recorded)[1].value), "9");
}

// Checks beyond a value's type: Has (a null value is not given), the line of a value or of an
// item of its list (the map's own line when absent), and errors there.
TEST(ConfigReader, HasLineAndErrorsAtAValueOrListItem) {
  ConfigReader r(YAML::Load("a: 1\nnothing:\nlist:\n  - x\n  - y\nmap: {k: v}\n"), "ctx");
  int a = 0;
  std::string nothing;
  std::vector<std::string> list;
  r.Read("a", &a);
  r.Read("nothing", &nothing);
  r.Read("list", &list);
  const YAML::Node map = r.Child("map");
  ASSERT_TRUE(r.Finish().ok()) << r.Finish().message();
  EXPECT_TRUE(r.Has("a"));
  EXPECT_FALSE(r.Has("nothing"));
  EXPECT_FALSE(r.Has("absent"));
  EXPECT_EQ(r.Line("a"), 1);
  EXPECT_EQ(r.Line("list"), 4);
  EXPECT_EQ(r.Line("list", 1), 5);
  EXPECT_EQ(r.Line("list", 7), 4);  // beyond the list: the list's line
  EXPECT_EQ(r.Line("absent"), 1);   // the map's own
  EXPECT_EQ(r.Line(""), 1);
  EXPECT_EQ(r.Error("list", "y is not allowed", 1).message(), "ctx (line 5): y is not allowed");
  EXPECT_EQ(r.Error("a", "too small").code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.ErrorAt(map["k"], "bad entry").message(), "ctx (line 6): bad entry");
}

// ForFile: a file's own settings (the study manifest), messages as "PATH:LINE: ..." naming keys,
// the known keys listed in reading order; an estimator's messages stay as they were.
TEST(ConfigReader, ForFileNamesFileLineAndKeys) {
  const YAML::Node node = YAML::Load("name: x\nruns: many\n");
  ConfigReader r = ConfigReader::ForFile(node, "m.yaml", "the manifest");
  std::string name;
  int runs = 1;
  r.Read("name", &name);
  r.Read("runs", &runs);
  EXPECT_EQ(r.Finish().message(),
            "m.yaml:2: runs must be a decimal integer in [-2147483648, 2147483647], found 'many'");
  EXPECT_EQ(r.Error("name", "taken").message(), "m.yaml:1: taken");

  ConfigReader u = ConfigReader::ForFile(YAML::Load("zeta: 1\nnmae: x\n"), "m.yaml", "a sweep");
  double zeta = 0.0;
  u.Read("zeta", &zeta);
  u.Read("name", &name);
  u.Read("alpha", &zeta);
  EXPECT_EQ(u.Finish().message(),
            "m.yaml:2: unknown key 'nmae' in a sweep; known: zeta, name, alpha");

  ConfigReader list = ConfigReader::ForFile(YAML::Load("ids: {a: 1}\n"), "m.yaml", "x");
  std::vector<std::string> ids;
  list.Read("ids", &ids);
  EXPECT_EQ(list.Finish().message(),
            "m.yaml:1: ids must be a list of plain values ([a, b, ...]), found a map");

  EXPECT_EQ(
      ConfigReader::ForFile(YAML::Load("[1, 2]"), "m.yaml", "the manifest").Finish().message(),
      "m.yaml:1: the manifest must be a map");
  EXPECT_EQ(
      ConfigReader::ForFile(YAML::Load("{[1]: 2}"), "m.yaml", "the manifest").Finish().message(),
      "m.yaml:1: keys must be plain words");
}

TEST(LoadYamlText, RefusesRepeatedKeysSecondDocumentsAndAliasBombs) {
  EXPECT_THAT(LoadYamlText("a: 1\nb:\n  c: 1\n  c: 2\n", "f.yaml").status().message(),
              HasSubstr("f.yaml:4: duplicate key 'c'"));
  EXPECT_THAT(LoadYamlText("a: 1\n---\nb: 2\n", "f.yaml").status().message(),
              HasSubstr("f.yaml:2: a second YAML document"));
  // yaml-cpp's own LoadAll never returns on this one.
  EXPECT_THAT(LoadYamlText(",", "f.yaml").status().message(), HasSubstr("f.yaml:1: "));
  std::string bomb = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 9; ++i) {
    bomb += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) bomb += (k ? ", *a" : "*a") + std::to_string(i - 1);
    bomb += "]\n";
  }
  EXPECT_THAT(LoadYamlText(bomb, "f.yaml").status().message(), HasSubstr("aliases"));
  auto ok = LoadYamlText("a: 1\nb: [1, 2]\n", "f.yaml");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ((*ok)["a"].Scalar(), "1");
  EXPECT_TRUE(LoadYamlText("", "f.yaml").ok());  // an empty file is an empty configuration
}

TEST(LoadYamlFile, ExpectsARegularFile) {
  EXPECT_THAT(LoadYamlFile("/").status().message(), HasSubstr("expected a regular file"));
  EXPECT_THAT(LoadYamlFile("/dev/null").status().message(), HasSubstr("device"));
  EXPECT_EQ(LoadYamlFile("/nonexistent/x.yaml").status().code(), StatusCode::kNotFound);
}

// The public configuration value: parsed by the same loader (its checks, its messages), read
// by the estimators' own readers (unknown keys refused with the line), empty when it holds no
// keys, and written back as YAML that parses to the same map.
TEST(Config, ParsesLoadsAndReachesTheEstimatorsReaders) {
  EXPECT_TRUE(Config().empty());
  auto blank = Config::Parse("", "cfg.yaml");
  ASSERT_TRUE(blank.ok()) << blank.status().message();
  EXPECT_TRUE(blank->empty());
  EXPECT_THAT(Config::Parse("a: 1\na: 2\n", "cfg.yaml").status().message(),
              HasSubstr("cfg.yaml:2: duplicate key 'a'"));
  EXPECT_EQ(Config::Load("/nonexistent/x.yaml").status().code(), StatusCode::kNotFound);

  auto config = Config::Parse("lag_s: 5\npath_loss: global\n", "cfg.yaml");
  ASSERT_TRUE(config.ok()) << config.status().message();
  EXPECT_FALSE(config->empty());
  auto again = Config::Parse(config->ToYaml(), "again");
  ASSERT_TRUE(again.ok()) << again.status().message();
  EXPECT_EQ(again->node()["lag_s"].Scalar(), "5");
  EXPECT_EQ(again->node()["path_loss"].Scalar(), "global");
  const EstimatorRegistry& reg = EstimatorRegistry::Builtin();
  EXPECT_TRUE(reg.Create("fg-window", *config).ok());
  auto typo = Config::Parse("lag_s: 5\nlag_z: 5\n", "cfg.yaml");
  ASSERT_TRUE(typo.ok());
  EXPECT_THAT(reg.Create("fg-window", *typo).status().message(),
              HasSubstr("(line 2): unknown option 'lag_z'"));
}

}  // namespace
// The options every estimator reads, with their defaults: each recorded key, written back with
// its default, is accepted (so the list holds no key the YAML would refuse), and known defaults
// come out (fg-batch's lag_s 10, its nested pdr map, tarrio-kf's sigma_p_m).
TEST(OptionDefaults, EveryEstimatorsKeysRoundTrip) {
  const EstimatorRegistry& reg = EstimatorRegistry::Builtin();
  for (const std::string& id : reg.Ids()) {
    SCOPED_TRACE(id);
    auto defaults = reg.OptionDefaults(id);
    ASSERT_TRUE(defaults.ok()) << defaults.status().message();
    ASSERT_FALSE(defaults->empty());
    // All of them at once, nested by their dotted keys, written here independently.
    YAML::Node config(YAML::NodeType::Map);
    for (const OptionDefault& d : *defaults) {
      std::vector<std::string> path;
      std::string key = d.key;
      for (size_t dot; (dot = key.find('.')) != std::string::npos; key = key.substr(dot + 1)) {
        path.push_back(key.substr(0, dot));
      }
      std::vector<YAML::Node> chain = {config};
      for (const std::string& p : path) {
        if (!chain.back()[p]) chain.back()[p] = YAML::Node(YAML::NodeType::Map);
        chain.push_back(chain.back()[p]);
      }
      const double* x = std::get_if<double>(&d.value);
      if (x && std::isnan(*x)) {
        chain.back()[key] = YAML::Node();  // unset: null keeps the default
      } else {
        std::visit([&](const auto& v) { chain.back()[key] = v; }, d.value);
      }
    }
    EXPECT_GT(config.size(), 0u);
    auto est = reg.Create(id, config);
    EXPECT_TRUE(est.ok()) << est.status().message();
  }
  auto fg = reg.OptionDefaults("fg-batch");
  ASSERT_TRUE(fg.ok());
  auto find = [&](const std::string& key) -> const OptionDefault* {
    for (const OptionDefault& d : *fg) {
      if (d.key == key) return &d;
    }
    return nullptr;
  };
  ASSERT_NE(find("lag_s"), nullptr);
  EXPECT_EQ(std::get<double>(find("lag_s")->value), 10.0);
  ASSERT_NE(find("path_loss"), nullptr);
  EXPECT_EQ(std::get<std::string>(find("path_loss")->value), "auto");
  bool nested = false;
  for (const OptionDefault& d : *fg) nested |= d.key.rfind("pdr.", 0) == 0;
  EXPECT_TRUE(nested);
  EXPECT_FALSE(reg.OptionDefaults("no-such-estimator").ok());
}

}  // namespace walkgraph
