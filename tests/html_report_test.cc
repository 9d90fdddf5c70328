// The report page (report.html). Without a browser: the table (families, best values, diverged
// and failed estimators apart), the JSON the plots are drawn from, decimation and determinism.
// In headless Chromium (Debian's `chromium`): the page as drawn by its script — the layout
// self-check the script writes into #wg-check (a distinct colour per estimator, no legend box
// over a plot area), the screenshot (not blank, each estimator's colour on screen), and that the
// self-check does report a legend moved over a plot. The Chromium tests are skipped when
// chromium is not installed, unless WALKGRAPH_REQUIRE_CHROMIUM is set (CI).
#include <png.h>
#include <stdlib.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "walkgraph/compare.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

constexpr int kWidth = 1500, kHeight = 2400;

bool HaveChromium() { return std::system("command -v chromium > /dev/null 2>&1") == 0; }

// A rectangle walked at 1 m/s for 60 s (truth every 0.5 s), three anchors.
Walk Rectangle() {
  Walk w;
  w.meta.name = "report-rectangle";
  w.meta.truth_kind = TruthKind::kContinuous;
  w.anchors = {{1, Eigen::Vector3d(-2, -2, 0)},
               {2, Eigen::Vector3d(17, -2, 0)},
               {3, Eigen::Vector3d(8, 13, 0)}};
  for (int k = 0; k <= 120; ++k) {
    const double s = 0.5 * k;  // metres along 15 x 15
    const double u = std::fmod(s, 60.0);
    Eigen::Vector2d p = u < 15   ? Eigen::Vector2d(u, 0)
                        : u < 30 ? Eigen::Vector2d(15, u - 15)
                        : u < 45 ? Eigen::Vector2d(45 - u, 15)
                                 : Eigen::Vector2d(0, 60 - u);
    TruthSample t;
    t.t_s = 0.5 * k;
    t.position_m = Eigen::Vector3d(p.x(), p.y(), 0);
    w.truth.push_back(t);
  }
  return w;
}

// Test-only estimator: the truth with a drift growing as scale·t (direction by `phase`), with a
// position covariance when `cov`; fails when scale < 0; runs away to 10 km when scale > 100.
class Drift : public Estimator {
 public:
  Drift(double scale, double phase, bool cov) : scale_(scale), phase_(phase), cov_(cov) {}
  Status CheckApplicable(const Walk&) const override { return Status::Ok(); }
  StatusOr<EstimateResult> Run(const Walk& walk) const override {
    if (scale_ < 0) return InternalError("drift: asked to fail");
    EstimateResult r;
    for (const TruthSample& t : walk.truth) {
      TrajectoryPoint p;
      p.t_s = t.t_s;
      const double e = scale_ > 100 ? 1e4 : scale_ * t.t_s;
      p.position_m = t.position_m + e * Eigen::Vector3d(std::cos(phase_), std::sin(phase_), 0);
      if (cov_) p.covariance = Eigen::Vector3d(0.1 + e * e, 0.05 + e * e / 4, 0.01).asDiagonal();
      r.trajectory.points.push_back(p);
    }
    return r;
  }

 private:
  double scale_, phase_;
  bool cov_;
};

// 26 ranked estimators over every family, plus one that diverges and one that fails.
EstimatorRegistry Registry(std::vector<std::string>* ids) {
  EstimatorRegistry r;
  int k = 0;
  const auto add = [&](const std::string& id, double scale) {
    const double phase = 0.7 * k++;
    const bool cov = k % 2 == 0;
    EXPECT_TRUE(r.Register({id, "test",
                            [=](const Config&) -> StatusOr<std::unique_ptr<Estimator>> {
                              return std::unique_ptr<Estimator>(new Drift(scale, phase, cov));
                            }})
                    .ok());
    ids->push_back(id);
  };
  for (const char* family : {"fg-", "tarrio-", "correa-", "prieto-", "gadeke-", "jimenez-"}) {
    for (int i = 0; i < 3; ++i) add(family + std::to_string(i), 0.005 + 0.004 * k);
  }
  for (const char* id : {"pdr-only", "rss-only", "odometry-dr", "zupt-ins", "fg-runaway", "fg-x",
                         "tarrio-x", "correa-x"}) {
    add(id, 0.01 + 0.003 * k);
  }
  add("fg-broken", -1.0);
  add("prieto-runaway", 1000.0);
  return r;
}

struct Report {
  Comparison comparison;
  std::string html;
};

Report MakeReport() {
  std::vector<std::string> ids;
  const EstimatorRegistry registry = Registry(&ids);
  CompareOptions options;
  options.estimator_ids = ids;
  auto c = CompareOnWalk(Rectangle(), options, registry);
  EXPECT_TRUE(c.ok()) << c.status().message();
  for (EstimatorOutcome& o : c->outcomes) o.runtime_s = 0.001 * o.id.size();
  return {*c, RenderHtmlReport(*c)};
}

std::string Between(const std::string& s, const std::string& a, const std::string& b) {
  const size_t i = s.find(a);
  if (i == std::string::npos) return "";
  const size_t j = s.find(b, i + a.size());
  return j == std::string::npos ? "" : s.substr(i + a.size(), j - i - a.size());
}

int CountSubstr(const std::string& s, const std::string& needle) {
  int n = 0;
  for (size_t pos = s.find(needle); pos != std::string::npos; pos = s.find(needle, pos + 1)) ++n;
  return n;
}

// An estimator scored on part of the truth (its estimate does not span the walk) keeps its
// row and figures, shows its points as "a/b", and is never marked best nor named lowest RMSE.
TEST(ReportPage, NeverMarksBestAnEstimatorScoredOnPartOfTheWalk) {
  Report r = MakeReport();
  int most = 0;
  for (const EstimatorOutcome& o : r.comparison.outcomes) most = std::max(most, o.stats.n_points);
  for (EstimatorOutcome& o : r.comparison.outcomes) {
    if (o.id == "fg-0") o.stats.n_points = most - 5;
  }
  const std::string html = RenderHtmlReport(r.comparison);
  const std::string table = Between(html, "<table id=\"results\">", "</table>");
  const std::string fg0 = Between(table, "data-id=\"fg-0\"", "</tr>");
  ASSERT_FALSE(fg0.empty());
  EXPECT_THAT(fg0, Not(HasSubstr("class=\"best\"")));
  EXPECT_THAT(fg0, HasSubstr(std::to_string(most - 5) + "/" + std::to_string(most)));
  EXPECT_THAT(html, Not(HasSubstr("Lowest RMSE: <b>fg-0</b>")));
  EXPECT_THAT(html, HasSubstr("never marked best"));
  EXPECT_THAT(r.html, Not(HasSubstr("never marked best")));  // every estimator spans the walk
}

// The walk's warnings (Comparison::warnings) stand under the table, escaped, with how many
// more results.json counts; a walk without any has no warnings block.
TEST(ReportPage, ShowsTheWalksWarningsUnderTheTable) {
  Report r = MakeReport();
  r.comparison.warnings = {"rss.csv:7: a <reading> & more", "walk.yaml: no initial_pose"};
  r.comparison.warning_count = 5;
  const std::string html = RenderHtmlReport(r.comparison);
  const std::string block = Between(html, "<div id=\"warnings\"", "</div>");
  EXPECT_THAT(block, HasSubstr("<b>Warnings</b> (5)"));
  EXPECT_THAT(block, HasSubstr("<li>rss.csv:7: a &lt;reading&gt; &amp; more</li>"));
  EXPECT_THAT(block, HasSubstr("<li>walk.yaml: no initial_pose</li>"));
  EXPECT_THAT(block, HasSubstr("and 3 more (counted in results.json)"));
  EXPECT_LT(html.find("</table>"), html.find("<div id=\"warnings\""));
  r.comparison.warnings.clear();
  r.comparison.warning_count = 0;
  EXPECT_THAT(RenderHtmlReport(r.comparison), Not(HasSubstr("id=\"warnings\"")));
}

// ANEES is best closest to 2 in ratio: 1.5 (1.33x too cautious) beats 2.8 (1.4x too
// confident), and 0.01 (a covariance that says nothing) beats nobody at 9.
TEST(ReportPage, AneesIsBestClosestToTwoInRatio) {
  Report r = MakeReport();
  const std::map<std::string, double> anees = {{"fg-0", 2.8}, {"fg-1", 1.5}, {"fg-2", 0.01}};
  for (EstimatorOutcome& o : r.comparison.outcomes) {
    o.stats.anees = anees.count(o.id) ? anees.at(o.id) : 9.0;
  }
  const std::string html = RenderHtmlReport(r.comparison);
  const std::string table = Between(html, "<table id=\"results\">", "</table>");
  EXPECT_THAT(Between(table, "data-id=\"fg-1\"", "</tr>"),
              HasSubstr("data-v=\"1.50000\" class=\"best\""));
  EXPECT_THAT(Between(table, "data-id=\"fg-0\"", "</tr>"),
              Not(HasSubstr("data-v=\"2.80000\" class=\"best\"")));
  EXPECT_THAT(Between(table, "data-id=\"fg-2\"", "</tr>"),
              Not(HasSubstr("data-v=\"0.01000\" class=\"best\"")));
}

TEST(ReportPage, TableGroupsByFamilyMarksBestAndSetsUnrankedApart) {
  const Report r = MakeReport();
  const std::string table = Between(r.html, "<table id=\"results\">", "</table>");
  ASSERT_FALSE(table.empty());
  EXPECT_EQ(CountSubstr(table, "<tr class=\"est\""), 26);
  // Families in order: fg rows first, then tarrio, ..., baselines last.
  EXPECT_LT(table.find("data-id=\"fg-x\""), table.find("data-id=\"tarrio-0\""));
  EXPECT_LT(table.find("data-id=\"tarrio-x\""), table.find("data-id=\"correa-0\""));
  EXPECT_LT(table.find("data-id=\"jimenez-2\""), table.find("data-id=\"pdr-only\""));
  EXPECT_EQ(CountSubstr(table, "<tr class=\"fam\""), 7);
  // fg-0 drifts least: best RMSE, marked once in that column.
  const std::string fg0 = Between(table, "data-id=\"fg-0\"", "</tr>");
  EXPECT_THAT(fg0, HasSubstr("class=\"best\""));
  EXPECT_THAT(r.html, HasSubstr("Lowest RMSE: <b>fg-0</b>"));
  // The run-away estimator has the smallest errors before it leaves: never ranked nor best.
  EXPECT_THAT(table, Not(HasSubstr("prieto-runaway")));
  EXPECT_THAT(table, Not(HasSubstr("fg-broken")));
  const std::string unranked = Between(r.html, "<table id=\"unranked\">", "</table>");
  EXPECT_THAT(unranked, HasSubstr("prieto-runaway"));
  EXPECT_THAT(unranked, HasSubstr("outside the scene"));
  EXPECT_THAT(unranked, HasSubstr("failed: drift: asked to fail"));
  // ANEES is best closest to 2, not smallest.
  EXPECT_THAT(r.html, HasSubstr("closest to 2"));
}

TEST(ReportPage, DataBlockHoldsRankedEstimatorsWithDistinctColours) {
  const Report r = MakeReport();
  const std::string json =
      Between(r.html, "<script type=\"application/json\" id=\"wg-data\">", "</script>");
  const nlohmann::json d = nlohmann::json::parse(json);
  ASSERT_EQ(d["est"].size(), 26u);
  std::set<std::string> colours;
  for (const auto& e : d["est"]) {
    EXPECT_TRUE(colours.insert(e["c"].get<std::string>()).second) << e["id"];
    EXPECT_EQ(e["q"].size(), 101u);
    EXPECT_EQ(e["er"].size() % 5, 0u);
    EXPECT_LE(e["el"].size(), 5u * 31);
  }
  EXPECT_EQ(d["anchors"].size(), 3u);
  EXPECT_EQ(d["truth"].size(), 2u * 121);
  // Offline: no URL is loaded (only the SVG namespace string appears).
  EXPECT_THAT(r.html, Not(HasSubstr(" src=")));
  EXPECT_THAT(r.html, Not(HasSubstr("<link")));
  EXPECT_EQ(CountSubstr(r.html, "http"), 1);
}

// Same comparison, same bytes; a long walk is decimated for the plots.
TEST(ReportPage, DeterministicAndDecimated) {
  const Report a = MakeReport(), b = MakeReport();
  EXPECT_EQ(a.html, b.html);
  Comparison c = a.comparison;
  EstimatorOutcome& o = c.outcomes[0];
  Trajectory& t = o.result.trajectory;
  ErrorSeries& e = o.errors;
  for (int i = 0; i < 200000; ++i) {
    TrajectoryPoint p = t.points.back();
    p.t_s += 0.01;
    t.points.push_back(p);
    e.t_s.push_back(p.t_s);
    e.error_m.push_back(1.0);
    e.distance_m.push_back(1.0);
  }
  e.nees.clear();
  const std::string big = RenderHtmlReport(c);
  EXPECT_LT(big.size(), a.html.size() + 60000) << "the 200k points must be decimated";
}

// ------------------------------------------------------------------ in headless Chromium

std::string Chromium(const std::string& profile, const std::string& args) {
  return "timeout 120 chromium --headless --no-sandbox --disable-gpu "
         "--disable-background-networking --disable-component-update --disable-sync "
         "--no-first-run --hide-scrollbars --user-data-dir=" +
         profile + " " + args;
}

struct Rgb {
  int w = 0, h = 0;
  std::vector<uint8_t> px;
  const uint8_t* at(int x, int y) const { return &px[3 * (static_cast<size_t>(y) * w + x)]; }
};

Rgb ReadPng(const std::string& path) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  Rgb out;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return out;
  image.format = PNG_FORMAT_RGB;
  out.px.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out.px.data(), 0, nullptr)) {
    out.px.clear();
    return out;
  }
  out.w = static_cast<int>(image.width);
  out.h = static_cast<int>(image.height);
  return out;
}

int CountColour(const Rgb& img, int r, int g, int b, int tol) {
  int n = 0;
  for (int y = 0; y < img.h; ++y) {
    for (int x = 0; x < img.w; ++x) {
      const uint8_t* p = img.at(x, y);
      if (std::abs(p[0] - r) <= tol && std::abs(p[1] - g) <= tol && std::abs(p[2] - b) <= tol) ++n;
    }
  }
  return n;
}

class HtmlReport : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!HaveChromium()) {
      if (std::getenv("WALKGRAPH_REQUIRE_CHROMIUM") != nullptr) {
        FAIL() << "chromium is not installed but WALKGRAPH_REQUIRE_CHROMIUM is set";
      }
      GTEST_SKIP() << "chromium is not installed: the report is not checked in a browser";
    }
    char tmpl[] = "/tmp/wg_report_XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    report_ = MakeReport();
    ASSERT_TRUE(WriteComparison(report_.comparison, (dir_ / "out").string()).ok());
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  // The DOM after the page's script ran, and its self-check.
  nlohmann::json DumpCheck(const fs::path& page, std::string* dom_out = nullptr) {
    const fs::path profile = dir_ / ("profile" + std::to_string(++profiles_));
    fs::create_directories(profile);
    const std::string dom_path = (dir_ / "dom.html").string();
    const std::string cmd =
        Chromium(profile.string(),
                 "--window-size=" + std::to_string(kWidth) + "," + std::to_string(kHeight) +
                     " --virtual-time-budget=5000 --dump-dom file://" + page.string()) +
        " > " + dom_path + " 2> /dev/null";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(dom_path);
    const std::string dom((std::istreambuf_iterator<char>(in)), {});
    if (dom_out != nullptr) *dom_out = dom;
    const std::string text = Between(dom, "<pre id=\"wg-check\">", "</pre>");
    return nlohmann::json::parse(std::regex_replace(text, std::regex("&quot;"), "\""), nullptr,
                                 false);
  }
  fs::path dir_;
  Report report_;
  int profiles_ = 0;
};

TEST_F(HtmlReport, EveryEstimatorHasItsOwnColourAndNoLegendCoversAPlot) {
  std::string dom;
  const auto start = std::chrono::steady_clock::now();
  const nlohmann::json check = DumpCheck(dir_ / "out" / "report.html", &dom);
  std::cout << "chromium --dump-dom: "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
  ASSERT_FALSE(check.is_discarded()) << "no self-check in the DOM: did the script run?";
  EXPECT_EQ(check["estimators"], 26);
  EXPECT_EQ(check["distinct_colours"], 26);
  // The colour each line was drawn with is the swatch of its row in the table.
  for (const auto& [id, colour] : check["colours"].items()) {
    ASSERT_TRUE(colour.is_string()) << id << " has no line in the trajectory plot";
    EXPECT_THAT(dom, HasSubstr("data-id=\"" + id + "\"")) << id;
    const std::string row = Between(dom, "<tr class=\"est\" data-id=\"" + id + "\"", "</td>");
    EXPECT_THAT(row, HasSubstr("background:" + colour.get<std::string>())) << id;
  }
  EXPECT_FALSE(check["colours"].contains("prieto-runaway"));
  EXPECT_GE(check["legend_boxes"], 3);
  // trajectories, error vs time and vs distance, CDF, box, ellipses, NEES + 26 APE panels
  // (the Monte Carlo box plot is hidden on a single walk).
  EXPECT_EQ(check["plot_areas"], 7 + 26);
  EXPECT_TRUE(check["overlaps"].empty()) << check["overlaps"].dump();
  for (const char* id : {"s-p-traj", "s-p-time", "s-p-dist", "s-p-cdf", "s-p-box", "s-p-ell",
                         "s-p-nees", "s-ape-fg-0"}) {
    EXPECT_THAT(dom, HasSubstr("id=\"" + std::string(id) + "\"")) << id;
  }
  EXPECT_EQ(CountSubstr(dom, "class=\"anchor\""), 3);
  EXPECT_GE(CountSubstr(dom, "<ellipse"), 10);
}

TEST_F(HtmlReport, ScreenshotShowsEveryEstimatorsColour) {
  const fs::path profile = dir_ / "shot-profile";
  fs::create_directories(profile);
  const std::string png = (dir_ / "shot.png").string();
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(std::system(
                (Chromium(profile.string(),
                          "--screenshot=" + png + " --window-size=" + std::to_string(kWidth) + "," +
                              std::to_string(kHeight) + " --virtual-time-budget=5000 file://" +
                              (dir_ / "out" / "report.html").string()) +
                 " > /dev/null 2>&1")
                    .c_str()),
            0);
  std::cout << "chromium --screenshot: "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
  if (const char* keep = std::getenv("WALKGRAPH_KEEP_SCREENSHOT"))
    fs::copy_file(png, keep, fs::copy_options::overwrite_existing);
  const Rgb img = ReadPng(png);
  ASSERT_EQ(img.w, kWidth);
  ASSERT_EQ(img.h, kHeight);
  const int white = CountColour(img, 255, 255, 255, 8);
  EXPECT_GT(1.0 - static_cast<double>(white) / (kWidth * kHeight), 0.03) << "(nearly) blank";
  // Each estimator's swatches (table and legend, 12 x 12 px of its exact colour) are on screen.
  const std::string json = Between(report_.html, "id=\"wg-data\">", "</script>");
  const nlohmann::json d = nlohmann::json::parse(json);
  for (const auto& e : d["est"]) {
    const long v = std::strtol(e["c"].get<std::string>().c_str() + 1, nullptr, 16);
    EXPECT_GT(CountColour(img, v >> 16, (v >> 8) & 255, v & 255, 2), 150) << e["id"];
  }
  // The truth (black) and the anchors (#f0c000) are drawn.
  EXPECT_GT(CountColour(img, 0, 0, 0, 30), 500);
  EXPECT_GT(CountColour(img, 0xf0, 0xc0, 0x00, 30), 30);
}

// Sorting by a column (ungrouped, descending), hiding an estimator and pinning a row's highlight
// work in the browser: a script appended to the page clicks them and records the outcome.
TEST_F(HtmlReport, TableSortsTogglesAndHighlights) {
  std::string html = report_.html;
  const size_t end = html.rfind("</body>");
  ASSERT_NE(end, std::string::npos);
  html.insert(end, R"(<script>
const th = document.querySelector('#results thead th[data-col="1"]');
th.click(); th.click();
document.getElementById('group').click();
document.querySelector('tr.est[data-id="fg-0"] input.tog').click();
document.querySelector('tr.est[data-id="tarrio-1"]').click();
document.body.setAttribute('data-order', Array.from(document.querySelectorAll('#results tr.est'))
  .map(r => r.getAttribute('data-id') + (r.classList.contains('off') ? '(off)' : '')).join(' '));
document.body.setAttribute('data-hl', String(document.querySelectorAll('svg .hl').length));
</script>)");
  const fs::path page = dir_ / "clicked.html";
  std::ofstream(page) << html;
  std::string dom;
  DumpCheck(page, &dom);
  const std::string order = Between(dom, "data-order=\"", "\"");
  // RMSE descending over all families: the estimators' RMSE from the comparison, sorted.
  std::vector<std::pair<double, std::string>> rmse;
  for (const EstimatorOutcome& o : report_.comparison.outcomes) {
    if (o.Ranked()) rmse.emplace_back(o.stats.rmse_m, o.id);
  }
  std::sort(rmse.rbegin(), rmse.rend());
  std::string expected;
  for (const auto& [v, id] : rmse)
    expected += (expected.empty() ? "" : " ") + id + (id == "fg-0" ? "(off)" : "");
  EXPECT_EQ(order, expected);
  // tarrio-1's lines in the trajectory, error, CDF and box plots are highlighted.
  EXPECT_GE(std::stoi(Between(dom, "data-hl=\"", "\"")), 5);
}

// The self-check is not vacuous: a legend moved over the trajectory plot is reported.
TEST_F(HtmlReport, SelfCheckReportsALegendOverAPlot) {
  std::string html = report_.html;
  const size_t head = html.find("</head>");
  ASSERT_NE(head, std::string::npos);
  html.insert(head, "<style>#legend{position:absolute;left:400px;top:900px}</style>");
  const fs::path page = dir_ / "moved.html";
  std::ofstream(page) << html;
  const nlohmann::json check = DumpCheck(page);
  ASSERT_FALSE(check.is_discarded());
  ASSERT_FALSE(check["overlaps"].empty());
}

}  // namespace
}  // namespace walkgraph
