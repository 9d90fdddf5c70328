// The report page as a browser draws it: renders report.html from a comparison on a small
// walk, loads it in headless Chromium (Debian's `chromium`), and checks the parsed DOM (the
// plots and the table are there) and the screenshot (not blank; each plot has its curves).
// Skipped when chromium is not installed, unless WALKGRAPH_REQUIRE_CHROMIUM is set (CI).
#include <png.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "walkgraph/compare.h"
#include "walkgraph/io.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr int kWidth = 1400, kHeight = 1500;

bool HaveChromium() { return std::system("command -v chromium > /dev/null 2>&1") == 0; }

// A seeded odometry walk around a rectangle with three anchors; dead reckoning drifts from it.
Walk Rectangle() {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.03);
  Walk w;
  w.meta.name = "report-rectangle";
  w.meta.truth_kind = TruthKind::kContinuous;
  w.meta.initial_pose = InitialPose{};
  w.anchors = {{1, Eigen::Vector3d(-2, -2, 0)},
               {2, Eigen::Vector3d(12, -2, 0)},
               {3, Eigen::Vector3d(5, 8, 0)}};
  Eigen::Vector2d p(0, 0);
  double heading = 0.0;
  w.truth.push_back(TruthSample{});
  for (int k = 1; k <= 60; ++k) {
    const bool corner = k % 15 == 0;
    OdometrySample o;
    o.t_s = 0.5 * k;
    o.dist_m = 0.5 + noise(rng);
    o.dheading_rad = (corner ? M_PI / 2 : 0.0) + noise(rng);
    w.odometry.push_back(o);
    p += 0.5 * Eigen::Vector2d(std::cos(heading), std::sin(heading));
    if (corner) heading += M_PI / 2;
    TruthSample t;
    t.t_s = o.t_s;
    t.position_m = Eigen::Vector3d(p.x(), p.y(), 0.0);
    w.truth.push_back(t);
  }
  return w;
}

std::string Chromium(const std::string& profile, const std::string& args) {
  return "timeout 120 chromium --headless --no-sandbox --disable-gpu "
         "--disable-background-networking --disable-component-update --disable-sync "
         "--no-first-run --user-data-dir=" +
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

// Pixels in [x0, x1) × [y0, y1) within `tol` of colour (r, g, b) on every channel.
int CountColour(const Rgb& img, int x0, int y0, int x1, int y1, int r, int g, int b, int tol) {
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(img.h, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(img.w, x1); ++x) {
      const uint8_t* p = img.at(x, y);
      if (std::abs(p[0] - r) <= tol && std::abs(p[1] - g) <= tol && std::abs(p[2] - b) <= tol) ++n;
    }
  }
  return n;
}

int CountSubstr(const std::string& s, const std::string& needle) {
  int n = 0;
  for (size_t pos = s.find(needle); pos != std::string::npos; pos = s.find(needle, pos + 1)) ++n;
  return n;
}

TEST(HtmlReport, ChromiumDrawsThePlotsAndTheTable) {
  if (!HaveChromium()) {
    if (std::getenv("WALKGRAPH_REQUIRE_CHROMIUM") != nullptr) {
      FAIL() << "chromium is not installed but WALKGRAPH_REQUIRE_CHROMIUM is set";
    }
    GTEST_SKIP() << "chromium not installed";
  }
  CompareOptions options;
  options.estimator_ids = {"odometry-dr"};  // the colour checks look for the first line's colour
  auto c = CompareOnWalk(Rectangle(), options);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_TRUE(c->outcomes[0].status.ok());
  ASSERT_GT(c->outcomes[0].stats.max_m, 0.1);  // a visible error curve
  char tmpl[] = "/tmp/wg_report_XXXXXX";
  ASSERT_NE(::mkdtemp(tmpl), nullptr);
  const fs::path dir(tmpl);
  ASSERT_TRUE(WriteComparison(*c, (dir / "out").string()).ok());
  const std::string url = "file://" + (dir / "out" / "report.html").string();

  // The DOM as Chromium parsed it.
  fs::create_directories(dir / "profile1");
  const std::string dom_path = (dir / "dom.html").string();
  ASSERT_EQ(std::system((Chromium((dir / "profile1").string(), "--dump-dom " + url) + " > " +
                         dom_path + " 2> /dev/null")
                            .c_str()),
            0);
  std::ifstream dom_in(dom_path);
  std::stringstream dom_s;
  dom_s << dom_in.rdbuf();
  const std::string dom = dom_s.str();
  for (const char* id :
       {"id=\"trajectories\"", "id=\"error-time\"", "id=\"error-cdf\"", "id=\"results\""}) {
    EXPECT_THAT(dom, HasSubstr(id));
  }
  EXPECT_EQ(CountSubstr(dom, "class=\"anchor\""), 3);
  EXPECT_GE(CountSubstr(dom, "<polyline"), 3);  // trajectory, error curve, CDF
  EXPECT_THAT(dom, HasSubstr("<td style=\"color:#1f77b4\">odometry-dr</td>"));

  // The screenshot.
  fs::create_directories(dir / "profile2");
  const std::string png = (dir / "shot.png").string();
  ASSERT_EQ(
      std::system((Chromium((dir / "profile2").string(),
                            "--screenshot=" + png + " --window-size=" + std::to_string(kWidth) +
                                "," + std::to_string(kHeight) + " " + url) +
                   " > /dev/null 2>&1")
                      .c_str()),
      0);
  const Rgb img = ReadPng(png);
  ASSERT_EQ(img.w, kWidth);
  ASSERT_EQ(img.h, kHeight);
  const int white = CountColour(img, 0, 0, kWidth, kHeight, 255, 255, 255, 8);
  const double inked = 1.0 - static_cast<double>(white) / (kWidth * kHeight);
  EXPECT_GT(inked, 0.01) << "screenshot is (nearly) blank";
  // Layout at 1400 px: the table, then two 640 px plots per row (trajectories, error vs time),
  // then the CDF. The estimator's colour #1f77b4 must appear in each plot's area, the anchors'
  // #f0c000 and the black truth in the trajectory plot.
  const int row1 = 170, row2 = 620, row3 = 1100, col = 700;
  EXPECT_GT(CountColour(img, 0, row1, col, row2, 0x1f, 0x77, 0xb4, 40), 100) << "trajectories";
  EXPECT_GT(CountColour(img, col, row1, kWidth, row2, 0x1f, 0x77, 0xb4, 40), 100)
      << "error vs time";
  EXPECT_GT(CountColour(img, 0, row2, col, row3, 0x1f, 0x77, 0xb4, 40), 100) << "error CDF";
  EXPECT_GT(CountColour(img, 0, row1, col, row2, 0xf0, 0xc0, 0x00, 40), 30) << "anchors";
  EXPECT_GT(CountColour(img, 0, row1, col, row2, 0, 0, 0, 40), 100) << "truth";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace walkgraph
