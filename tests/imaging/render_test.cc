// The slice/MIP panel and the 3D view of imaging/render, and `echoservo render`.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <thread>

#include "imaging/io/volume_io.h"
#include "imaging/render/png_file.h"
#include "imaging/render/volume_render.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::RunCli;
using echoservo::testing::RunResult;
using echoservo::testing::RunShell;
using echoservo::testing::ShellQuote;
using echoservo::testing::TempDir;

// A written panel as OpenCV BGR, the order the pixel checks below use.
cv::Mat ReadBgr(const std::filesystem::path& png) {
  const RgbImage rgb = ReadPngRgb(png);
  cv::Mat bgr(rgb.height, rgb.width, CV_8UC3);
  for (int y = 0; y < rgb.height; ++y) {
    for (int x = 0; x < rgb.width; ++x) {
      bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(rgb.At(x, y, 2), rgb.At(x, y, 1), rgb.At(x, y, 0));
    }
  }
  return bgr;
}

const PhantomSpec kSpec;  // line (4,5,6)→(14,12,30) mm, sphere (17,10,38) r 4 mm

cv::Vec3b PixelAt(const cv::Mat& img, const Eigen::Vector2d& p) {
  return img.at<cv::Vec3b>(static_cast<int>(std::lround(p.y())),
                           static_cast<int>(std::lround(p.x())));
}

// Whether some pixel within `radius` of p satisfies `pred` (BGR).
template <class Pred>
bool AnyNear(const cv::Mat& img, const Eigen::Vector2d& p, int radius, Pred pred) {
  const int cx = static_cast<int>(std::lround(p.x())), cy = static_cast<int>(std::lround(p.y()));
  for (int y = cy - radius; y <= cy + radius; ++y) {
    for (int x = cx - radius; x <= cx + radius; ++x) {
      if (x >= 0 && y >= 0 && x < img.cols && y < img.rows && pred(img.at<cv::Vec3b>(y, x))) {
        return true;
      }
    }
  }
  return false;
}

bool IsGrey(const cv::Vec3b& c) { return c[0] == c[1] && c[1] == c[2]; }
bool IsRed(const cv::Vec3b& c) { return c[2] > 180 && c[0] < 130 && c[1] < 130; }
bool IsGreen(const cv::Vec3b& c) { return c[1] > 160 && c[0] < 130 && c[2] < 130; }
bool IsCyan(const cv::Vec3b& c) { return c[0] > 180 && c[1] > 160 && c[2] < 100; }
bool IsYellow(const cv::Vec3b& c) { return c[1] > 160 && c[2] > 180 && c[0] < 100; }

TEST(RenderSlices, WritesPngOfTheLayoutSize) {
  TempDir dir("render");
  const Volume v = MakeRenderPhantom();
  const auto png = dir.path() / "sub" / "slices.png";
  RenderSlicesPng(v, {}, png);
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, {});
  EXPECT_EQ(img.cols, layout.image_width);
  EXPECT_EQ(img.rows, layout.image_height);
  // Panels lie inside the image and do not overlap.
  for (std::size_t a = 0; a < 6; ++a) {
    const auto& p = layout.panels[a];
    EXPECT_GE(p.x0, 0);
    EXPECT_LE(p.x0 + p.width, img.cols);
    EXPECT_LE(p.y0 + p.height, img.rows);
    for (std::size_t b = a + 1; b < 6; ++b) {
      const auto& q = layout.panels[b];
      EXPECT_TRUE(
          cv::Rect(p.x0, p.y0, p.width, p.height).area() > 0 &&
          (cv::Rect(p.x0, p.y0, p.width, p.height) & cv::Rect(q.x0, q.y0, q.width, q.height))
                  .area() == 0);
    }
  }
}

TEST(RenderSlices, AnisotropicVoxelsKeepTheirAspect) {
  const Volume v = MakeRenderPhantom();  // 48×40×64 voxels of 0.5×0.5×0.75 mm
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, {});
  const auto& xz = layout.panels[1];
  EXPECT_EQ(xz.u_axis, 0);
  EXPECT_EQ(xz.v_axis, 2);
  EXPECT_NEAR(static_cast<double>(xz.height) / xz.width, (64 * 0.75) / (48 * 0.5), 0.02);
  EXPECT_NEAR(xz.width / layout.pixels_per_mm, 24.0, 0.5);
  EXPECT_NEAR(xz.height / layout.pixels_per_mm, 48.0, 0.5);
}

TEST(RenderSlices, MipShowsTheLineWhereItProjects) {
  TempDir dir("render");
  const Volume v = MakeRenderPhantom();
  const auto png = dir.path() / "mip.png";
  RenderSlicesPng(v, {}, png);
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, {});
  for (int panel = 3; panel < 6; ++panel) {
    for (double t : {0.2, 0.5, 0.8}) {
      const Eigen::Vector3d p = kSpec.line_from_mm + t * (kSpec.line_to_mm - kSpec.line_from_mm);
      const cv::Vec3b c = PixelAt(img, ProjectToPanel(v, layout, panel, p));
      EXPECT_TRUE(IsGrey(c)) << "panel " << panel << " t " << t;
      EXPECT_GT(c[0], 180) << "panel " << panel << " t " << t;
    }
    // Background well away from the line and the sphere stays dark.
    const cv::Vec3b bg = PixelAt(img, ProjectToPanel(v, layout, panel, {22.0, 18.0, 2.0}));
    EXPECT_LT(bg[0], 40) << "panel " << panel;
    // The sphere's centre projects bright in every MIP.
    EXPECT_GT(PixelAt(img, ProjectToPanel(v, layout, panel, kSpec.sphere_centre_mm))[0], 150);
  }
  // The slices go through the centre by default: the z slice (k 32, z = 24 mm) cuts the
  // line at t = 0.75, so it shows bright there.
  EXPECT_EQ(layout.slice_index, Eigen::Vector3d(24, 20, 32));
}

TEST(RenderSlices, OverlayMarkersAtTheProjectedPoints) {
  TempDir dir("render");
  const Volume v = MakeRenderPhantom();
  RenderOverlays o;
  o.tip_mm = kSpec.line_to_mm;
  o.target_mm = kSpec.sphere_centre_mm;
  o.axis_point_mm = kSpec.line_from_mm;
  o.axis_direction = kSpec.line_to_mm - kSpec.line_from_mm;
  FrameGroundTruth truth;
  truth.catheter_visible = true;
  truth.tip_mm = kSpec.line_to_mm + Eigen::Vector3d(-3.0, 3.0, 2.0);
  truth.axis_point_mm = kSpec.line_from_mm;
  truth.axis_direction = (kSpec.line_to_mm - kSpec.line_from_mm).normalized();
  truth.target_visible = true;
  truth.target_mm = Eigen::Vector3d(6.0, 15.0, 40.0);
  o.truth = truth;
  o.title = "overlay test";
  const auto png = dir.path() / "overlay.png";
  RenderSlicesPng(v, o, png);
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, o);
  // Slices go through the tip by default.
  EXPECT_TRUE(layout.slice_index.isApprox(v.PhysicalToIndex(*o.tip_mm).array().round().matrix()));
  for (int panel = 0; panel < 6; ++panel) {
    EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, panel, *o.tip_mm), 1, IsRed))
        << "tip, panel " << panel;
    // The target diamond is hollow (14 px): look for its outline.
    EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, panel, *o.target_mm), 8, IsGreen))
        << "target, panel " << panel;
    EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, panel, truth.tip_mm), 1, IsCyan))
        << "true tip, panel " << panel;
    EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, panel, truth.target_mm), 8, IsCyan))
        << "true target, panel " << panel;
    const Eigen::Vector3d mid = 0.5 * (kSpec.line_from_mm + kSpec.line_to_mm);
    EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, panel, mid), 1, IsYellow))
        << "axis, panel " << panel;
    // No marker where nothing was given.
    EXPECT_FALSE(AnyNear(img, ProjectToPanel(v, layout, panel, {22.0, 18.0, 2.0}), 2, IsRed));
  }
}

TEST(RenderSlices, RejectsBadOverlays) {
  const Volume v = MakeRenderPhantom();
  RenderOverlays o;
  o.axis_point_mm = Eigen::Vector3d::Zero();
  o.axis_direction = Eigen::Vector3d::Zero();
  ExpectContains(
      echoservo::testing::InvalidArgumentMessage([&] { RenderSlicesPng(v, o, "/tmp/never.png"); }),
      "axis direction is zero");
  RenderOverlays nan;
  nan.tip_mm = Eigen::Vector3d(std::nan(""), 0, 0);
  ExpectContains(echoservo::testing::InvalidArgumentMessage(
                     [&] { RenderSlicesPng(v, nan, "/tmp/never.png"); }),
                 "tip is not finite");
}

TEST(RenderSlices, LargeVolumeIsScaledDown) {
  TempDir dir("render");
  PhantomSpec spec;
  spec.dims = {160, 64, 208};
  spec.spacing_mm = {0.4, 0.6, 0.5};
  const Volume v = MakeRenderPhantom(spec);
  const auto png = dir.path() / "large.png";
  RenderSlicesPng(v, {}, png);
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  EXPECT_LT(img.cols, 1400);
  EXPECT_LT(img.rows, 1000);
}

TEST(RenderIsosurface, WithoutDisplayThrowsAClearError) {
  const char* saved = std::getenv("DISPLAY");
  const std::string keep = saved != nullptr ? saved : "";
  ::unsetenv("DISPLAY");
  try {
    RenderIsosurfacePng(MakeRenderPhantom(), 128, {}, "/tmp/never_3d.png");
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    ExpectContains(e.what(), "--3d needs an X server (DISPLAY is not set)");
    ExpectContains(e.what(), "xvfb-run -a");
  }
  if (saved != nullptr) ::setenv("DISPLAY", keep.c_str(), 1);
}

TEST(RenderIsosurface, InProcessWhenADisplayIsAvailable) {
  if (!XDisplayAvailable()) GTEST_SKIP() << "no X display (run under xvfb-run -a)";
  TempDir dir("render");
  const auto png = dir.path() / "iso.png";
  RenderOverlays o;
  o.tip_mm = kSpec.line_to_mm;
  IsosurfaceOptions options;
  options.width = 320;
  options.height = 240;
  RenderIsosurfacePng(MakeRenderPhantom(), 128, o, png, options);
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 320);
  EXPECT_EQ(img.rows, 240);
}

// ---- the CLI ----

TEST(RenderCli, PhantomSlicesPng) {
  ECHOSERVO_REQUIRES_CLI();
  TempDir dir("render", true);
  const auto png = dir.path() / "cli.png";
  const auto r = RunCli("render --phantom --out " + ShellQuote(png.string()) +
                        " --tip 14,12,30 --target 17,10,38 --axis 4,5,6,10,7,24");
  ASSERT_EQ(r.rc, 0) << r.err;
  ExpectContains(r.out, "wrote");
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  RenderOverlays o;
  o.tip_mm = Eigen::Vector3d(14, 12, 30);
  const Volume v = MakeRenderPhantom();
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, o);
  EXPECT_EQ(img.cols, layout.image_width);
  EXPECT_TRUE(AnyNear(img, ProjectToPanel(v, layout, 3, *o.tip_mm), 1, IsRed));
}

TEST(RenderCli, BadOptionsNameTheOption) {
  ECHOSERVO_REQUIRES_CLI();
  TempDir dir("render", true);
  const std::string out = " --out " + ShellQuote((dir.path() / "x.png").string());
  auto r = RunCli("render --phantom --axis 1,2,3,4,5" + out);
  EXPECT_EQ(r.rc, 1);
  ExpectContains(r.err, "--axis");
  r = RunCli("render --phantom --tip 1,2" + out);
  EXPECT_EQ(r.rc, 1);
  ExpectContains(r.err, "--tip");
  r = RunCli("render " + ShellQuote((dir.path() / "missing.mha").string()) + out);
  EXPECT_EQ(r.rc, 1);
  ExpectContains(r.err, "no such file");
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "x.png"));
}

TEST(RenderCli, ThreeDWithoutDisplayFailsCleanly) {
  ECHOSERVO_REQUIRES_CLI();
  TempDir dir("render", true);
  const auto png = dir.path() / "3d.png";
  const auto r = RunShell("env -u DISPLAY " + std::string(ECHOSERVO_CLI) +
                          " render --phantom --3d --out " + ShellQuote(png.string()));
  EXPECT_EQ(r.rc, 1) << r.err;  // an exit, not an abort (that would read -1)
  ExpectContains(r.err, "--3d needs an X server (DISPLAY is not set); run under xvfb-run -a");
  EXPECT_FALSE(std::filesystem::exists(png));
}

TEST(RenderCli, ThreeDWithABadDisplayFailsCleanly) {
  ECHOSERVO_REQUIRES_CLI();
  TempDir dir("render", true);
  const auto png = dir.path() / "3d.png";
  const auto r = RunShell("DISPLAY=:9876 " + std::string(ECHOSERVO_CLI) +
                          " render --phantom --3d --out " + ShellQuote(png.string()));
  EXPECT_EQ(r.rc, 1) << r.err;
  ExpectContains(r.err, "cannot open X display ':9876'");
  EXPECT_FALSE(std::filesystem::exists(png));
}

TEST(RenderCli, ThreeDUnderXvfb) {
  ECHOSERVO_REQUIRES_CLI();
  if (RunShell("command -v xvfb-run").rc != 0) GTEST_SKIP() << "xvfb-run is not installed";
  TempDir dir("render", true);
  const auto png = dir.path() / "3d.png";
  // A display number and an auth file of this process's own: `xvfb-run -a` keeps its cookie
  // in ./.Xauthority by default, shared by every test started in this directory, and two
  // -a starts can race for the same number. Under load Xvfb can also be slow to accept
  // clients, so a failure to open the display is retried.
#if defined(ECHOSERVO_SANITIZED)
  // Sanitizer build only: no leak check in this process. At exit LeakSanitizer reports
  // ~240 bytes allocated from a module that is no longer mapped (the OpenGL driver that
  // libGLX dlopens and dlcloses under Xvfb; echoservo itself dlopens nothing), so the leak
  // cannot be ours nor be suppressed by name. Memory errors are still checked
  // (docs/reliability.md, "Sanitizers and fuzzing").
  const std::string env = "env ASAN_OPTIONS=\"${ASAN_OPTIONS}:detect_leaks=0\" ";
#else
  const std::string env;
#endif
  const std::string args = env + std::string(ECHOSERVO_CLI) +
                           " render --phantom --3d --volume-rendering --width 640 --height 480"
                           " --tip 14,12,30 --target 17,10,38 --axis 4,5,6,10,7,24 --out " +
                           ShellQuote(png.string());
  RunResult r;
  for (int attempt = 0; attempt < 4; ++attempt) {
    const int server = 200 + static_cast<int>(::getpid() % 500) + 7 * attempt;
    r = RunShell("xvfb-run -n " + std::to_string(server) + " -f " +
                 ShellQuote((dir.path() / ("xauth" + std::to_string(attempt))).string()) + " " +
                 args);
    if (r.rc == 0 || r.err.find("cannot open X display") == std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500 * (attempt + 1)));
  }
  ASSERT_EQ(r.rc, 0) << r.out << r.err;
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 640);
  EXPECT_EQ(img.rows, 480);
  // Something besides the background: the isosurface (warm white) and the red tip.
  int warm = 0, red = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      if (c[2] > 150 && c[1] > 130 && c[0] > 100 && c[2] >= c[0]) ++warm;
      if (IsRed(c)) ++red;
    }
  }
  EXPECT_GT(warm, 500);
  EXPECT_GT(red, 100);  // the tip sphere
}

}  // namespace
}  // namespace echoservo::imaging

namespace echoservo::imaging {
namespace {

TEST(RenderCli, ReadsAVolumeFile) {
  ECHOSERVO_REQUIRES_CLI();
  TempDir dir("render", true);
  const auto mha = dir.path() / "phantom.mha";
  WriteVolume(MakeRenderPhantom(), mha);
  const auto png = dir.path() / "file.png";
  auto r = echoservo::testing::RunCli("render " + echoservo::testing::ShellQuote(mha.string()) +
                                      " --tip 14,12,30 --out " +
                                      echoservo::testing::ShellQuote(png.string()));
  ASSERT_EQ(r.rc, 0) << r.err;
  const cv::Mat img = ReadBgr(png);
  ASSERT_FALSE(img.empty());
  RenderOverlays o;
  o.tip_mm = Eigen::Vector3d(14, 12, 30);
  const Volume v = MakeRenderPhantom();
  const SlicePanelLayout layout = ComputeSlicePanelLayout(v, o);
  EXPECT_EQ(img.cols, layout.image_width);
  EXPECT_EQ(img.rows, layout.image_height);
  // The MIP along z shows the line's midpoint bright.
  const Eigen::Vector2d mid = ProjectToPanel(v, layout, 3, {9.0, 8.5, 18.0});
  EXPECT_GT(img.at<cv::Vec3b>(static_cast<int>(std::lround(mid.y())),
                              static_cast<int>(std::lround(mid.x())))[1],
            180);

  r = echoservo::testing::RunCli("render " + echoservo::testing::ShellQuote(mha.string()) +
                                 " --frame 1 --out " +
                                 echoservo::testing::ShellQuote(png.string()));
  EXPECT_EQ(r.rc, 1);
  echoservo::testing::ExpectContains(r.err, "has only 1 frame");
}

}  // namespace
}  // namespace echoservo::imaging
