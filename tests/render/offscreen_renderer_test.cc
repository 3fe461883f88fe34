#include "ltlo/render/offscreen_renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

namespace ltlo::render {
namespace {

// A camera with non-integer, off-centre principal point and fx != fy.
PinholeCamera testCamera() { return PinholeCamera(150.0, 140.0, 77.3, 61.6, 160, 120); }

// A quad in the camera frame spanning pixel-space rectangle [u0, u1] x [v0, v1] at depth z_m.
Mesh quadAtDepth(const PinholeCamera& cam, double u0, double v0, double u1, double v1, double z_m) {
  Mesh mesh;
  for (const Vec2& uv : {Vec2(u0, v0), Vec2(u1, v0), Vec2(u1, v1), Vec2(u0, v1)}) {
    mesh.positions_o.push_back(cam.backProject(uv, z_m).cast<float>());
  }
  mesh.triangles = {0, 1, 2, 0, 2, 3};
  return mesh;
}

TEST(OffscreenRenderer, FrontoParallelPlaneDepthIsExact) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const double z_m = 2.0;
  const int plane = renderer.addMesh(quadAtDepth(cam, -50, -50, 250, 250, z_m));
  RenderView view{cam, SE3(), 0.05, 50.0};
  const RenderResult r = renderer.render(view, {{plane, SE3(), 1.0f, 7}});
  double max_err = 0.0;
  for (int v = 0; v < cam.height(); ++v)
    for (int u = 0; u < cam.width(); ++u)
      max_err = std::max(max_err, std::abs(r.depth_m.at<float>(v, u) - z_m));
  EXPECT_LT(max_err, 2e-4);
  EXPECT_EQ(r.labels.at<uint8_t>(60, 80), 7);
  EXPECT_EQ(r.bgr.at<cv::Vec3b>(60, 80), cv::Vec3b(255, 255, 255));
}

TEST(OffscreenRenderer, TiltedPlaneDepthMatchesRayIntersection) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  // Plane through (0, 0, 3) with normal n, seen from a camera displaced in the world.
  const Vec3 n = Vec3(0.3, -0.2, 1.0).normalized();
  const Vec3 p0(0, 0, 3);
  const Vec3 e1 = n.cross(Vec3::UnitX()).normalized(), e2 = n.cross(e1);
  Mesh mesh;
  for (const Vec2& c : {Vec2(-9, -9), Vec2(9, -9), Vec2(9, 9), Vec2(-9, 9)})
    mesh.positions_o.push_back((p0 + c.x() * e1 + c.y() * e2).cast<float>());
  mesh.triangles = {0, 1, 2, 0, 2, 3};
  const int plane = renderer.addMesh(mesh);
  const SE3 T_w_c(so3ExpQuat(Vec3(0.05, -0.1, 0.02)), Vec3(0.2, -0.1, 0.3));
  const RenderResult r = renderer.render({cam, T_w_c.inverse(), 0.05, 50.0}, {{plane, SE3()}});
  double max_err = 0.0;
  for (int v = 0; v < cam.height(); v += 3) {
    for (int u = 0; u < cam.width(); u += 3) {
      const Vec3 ray_c = cam.backProject(Vec2(u, v), 1.0);
      const Vec3 ray_w = T_w_c.rotationMatrix() * ray_c;
      const double s = n.dot(p0 - T_w_c.translation()) / n.dot(ray_w);  // z of the hit
      max_err = std::max(max_err, std::abs(r.depth_m.at<float>(v, u) - s) / s);
    }
  }
  EXPECT_LT(max_err, 1e-4);  // relative; 24-bit depth buffer
}

// Rectangle edges placed 0.1 px either side of pixel centres: coverage tells whether the projection
// lands within 0.1 px of the camera model, with the top-left pixel centre at (0, 0).
TEST(OffscreenRenderer, ProjectionMatchesCameraModelToSubPixel) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const int inside =
      renderer.addMesh(quadAtDepth(cam, 20 - 0.1, 30 - 0.1, 100 + 0.1, 90 + 0.1, 1.5));
  const int outside =
      renderer.addMesh(quadAtDepth(cam, 20 + 0.1, 30 + 0.1, 100 - 0.1, 90 - 0.1, 1.5));
  for (int pass = 0; pass < 2; ++pass) {
    const int first = pass == 0 ? 20 : 21, last_u = pass == 0 ? 100 : 99,
              last_v = pass == 0 ? 90 : 89;
    const int first_v = pass == 0 ? 30 : 31;
    const RenderResult r =
        renderer.render({cam, SE3(), 0.05, 50.0}, {{pass == 0 ? inside : outside, SE3(), 1.0f, 1}});
    int wrong = 0;
    for (int v = 0; v < cam.height(); ++v)
      for (int u = 0; u < cam.width(); ++u) {
        const bool expected = u >= first && u <= last_u && v >= first_v && v <= last_v;
        wrong += (r.labels.at<uint8_t>(v, u) == 1) != expected;
      }
    EXPECT_EQ(wrong, 0) << "pass " << pass;
  }
}

TEST(OffscreenRenderer, KnownPointsProjectOntoTheirPixels) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  // Tiny squares (0.3 px half-size) around projections of 3-D points, in a rotated world pose.
  const SE3 T_w_c(so3ExpQuat(Vec3(0.2, 0.1, -0.3)), Vec3(1, 2, 0.5));
  const std::vector<Vec3> points_c = {{0.1, -0.2, 1.0}, {-0.5, 0.3, 2.5}, {0.7, 0.4, 3.7}};
  std::vector<DrawItem> items;
  for (size_t i = 0; i < points_c.size(); ++i) {
    const Vec2 uv = cam.project(points_c[i]);
    const Vec2 centre(std::round(uv.x()), std::round(uv.y()));
    Mesh mesh = quadAtDepth(cam, centre.x() - 0.3, centre.y() - 0.3, centre.x() + 0.3,
                            centre.y() + 0.3, points_c[i].z());
    items.push_back({renderer.addMesh(mesh), T_w_c, 1.0f, static_cast<uint8_t>(10 + i)});
  }
  const RenderResult r = renderer.render({cam, T_w_c.inverse(), 0.05, 50.0}, items);
  EXPECT_EQ(cv::countNonZero(r.labels), 3);
  for (size_t i = 0; i < points_c.size(); ++i) {
    const Vec2 uv = cam.project(points_c[i]);
    const int u = static_cast<int>(std::round(uv.x())), v = static_cast<int>(std::round(uv.y()));
    EXPECT_EQ(r.labels.at<uint8_t>(v, u), 10 + i);
    EXPECT_NEAR(r.depth_m.at<float>(v, u), points_c[i].z(), 1e-4 * points_c[i].z());
  }
}

TEST(OffscreenRenderer, TextureColoursAndGainAreApplied) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  cv::Mat tex(8, 8, CV_8UC3, cv::Scalar(40, 120, 200));
  Mesh mesh = quadAtDepth(cam, -10, -10, 200, 200, 1.0);
  mesh.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.texture = renderer.addTexture(tex);
  const int id = renderer.addMesh(mesh);
  const RenderResult r = renderer.render({cam, SE3(), 0.05, 50.0}, {{id, SE3(), 0.5f, 3}});
  const cv::Vec3b px = r.bgr.at<cv::Vec3b>(50, 50);
  EXPECT_NEAR(px[0], 20, 1);
  EXPECT_NEAR(px[1], 60, 1);
  EXPECT_NEAR(px[2], 100, 1);
  EXPECT_EQ(r.labels.at<uint8_t>(50, 50), 3);
  // Vertex colours (baked shading) multiply the texture too.
  mesh.colours_rgb.assign(4, Eigen::Vector3f(0.5f, 1.0f, 0.25f));
  const int shaded = renderer.addMesh(mesh);
  const RenderResult s = renderer.render({cam, SE3(), 0.05, 50.0}, {{shaded, SE3(), 1.0f, 4}});
  const cv::Vec3b shaded_px = s.bgr.at<cv::Vec3b>(50, 50);  // BGR: blue x 0.25, red x 0.5
  EXPECT_NEAR(shaded_px[0], 10, 1);
  EXPECT_NEAR(shaded_px[1], 120, 1);
  EXPECT_NEAR(shaded_px[2], 100, 1);
  EXPECT_EQ(s.labels.at<uint8_t>(50, 50), 4);
}

TEST(OffscreenRenderer, NearerSurfaceWinsAndBackgroundHasNoDepth) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const int far_plane = renderer.addMesh(quadAtDepth(cam, 0, 0, 80, 200, 3.0));
  const int near_plane = renderer.addMesh(quadAtDepth(cam, 40, 0, 80, 200, 1.0));
  const RenderResult r = renderer.render({cam, SE3(), 0.05, 50.0},
                                         {{near_plane, SE3(), 1, 2}, {far_plane, SE3(), 1, 1}});
  EXPECT_EQ(r.labels.at<uint8_t>(50, 10), 1);
  EXPECT_EQ(r.labels.at<uint8_t>(50, 60), 2);
  EXPECT_NEAR(r.depth_m.at<float>(50, 60), 1.0, 1e-4);
  EXPECT_EQ(r.depth_m.at<float>(50, 150), 0.0f);
  EXPECT_EQ(r.labels.at<uint8_t>(50, 150), 0);
}

// A closed prism of n flat sides around z: every vertex on the radius (or the axis), outward faces,
// and seen side-on it covers its width and lies between the prism's inner and outer radius.
TEST(OffscreenRenderer, CylinderMeshIsAClosedPrismOfItsRadiusAndLength) {
  const double r = 0.3, length = 1.0;
  const int sides = 12;
  const Mesh mesh = makeCylinderMesh(r, length, sides, -1);
  ASSERT_EQ(mesh.triangles.size(), 3u * (2 * sides + 2 * sides));
  for (const Eigen::Vector3f& p : mesh.positions_o) {
    const double radial = std::hypot(p.x(), p.y());
    EXPECT_TRUE(std::abs(radial - r) < 1e-6 || radial < 1e-9) << radial;
    EXPECT_NEAR(std::abs(p.z()), 0.5 * length, 1e-6);
  }
  for (size_t k = 0; k < mesh.triangles.size(); k += 3) {  // normals point away from the centre
    const Eigen::Vector3f a = mesh.positions_o[mesh.triangles[k]], b = mesh.positions_o[mesh.triangles[k + 1]],
                          c = mesh.positions_o[mesh.triangles[k + 2]];
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0f), 0.0f) << k;
  }
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const int cylinder = renderer.addMesh(mesh);
  const SE3 T_c_o(so3ExpQuat(Vec3(0, 0.5 * M_PI, 0)), Vec3(0, 0, 3.0));  // axis along the camera's x
  const RenderResult result = renderer.render({cam, SE3(), 0.05, 50.0}, {{cylinder, T_c_o, 1.0f, 3}});
  const float z_centre = result.depth_m.at<float>(62, 77);
  EXPECT_GE(z_centre, 3.0 - r - 1e-4);
  EXPECT_LE(z_centre, 3.0 - r * std::cos(M_PI / sides) + 1e-4);
  int rows = 0;  // its height in pixels along the image column through the axis
  for (int v = 0; v < cam.height(); ++v) rows += result.labels.at<uint8_t>(v, 77) == 3;
  EXPECT_NEAR(rows, 2.0 * r * cam.fy() / 3.0, 3.0);
}

TEST(OffscreenRenderer, SplatsPointsAndLinesRender) {
  const PinholeCamera cam = testCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const Vec3 p_c = cam.backProject(Vec2(40, 40), 2.0);
  const int splats = renderer.addMesh(makeSplatMesh(
      {p_c.cast<float>()}, {Eigen::Vector3f(0, 0, -1)}, {0.05f}, {Eigen::Vector3f(1, 0, 0)}));
  PointSet points;
  points.positions_o = {cam.backProject(Vec2(120, 40), 2.0).cast<float>()};
  points.size_px = 3;
  LineSet lines;
  lines.positions_o = {cam.backProject(Vec2(10, 100), 2.0).cast<float>(),
                       cam.backProject(Vec2(150, 100), 2.0).cast<float>()};
  const RenderResult r =
      renderer.render({cam, SE3(), 0.05, 50.0}, {{splats, SE3(), 1, 1},
                                                 {renderer.addPoints(points), SE3(), 1, 2},
                                                 {renderer.addLines(lines), SE3(), 1, 3}});
  // Splat radius 0.05 m at 2 m = 3.75 px: its centre and a pixel 3 px away are covered.
  EXPECT_EQ(r.labels.at<uint8_t>(40, 40), 1);
  EXPECT_EQ(r.labels.at<uint8_t>(40, 43), 1);
  EXPECT_EQ(r.labels.at<uint8_t>(40, 46), 0);
  EXPECT_EQ(r.bgr.at<cv::Vec3b>(40, 40), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(r.labels.at<uint8_t>(40, 120), 2);
  EXPECT_EQ(r.labels.at<uint8_t>(100, 80), 3);
}

// ---- SplatSet: discs of a known size give a known silhouette --------------------------------

// One disc of radius r at distance z facing the camera, tilted by `tilt_rad` about the x axis.
SplatSet oneDisc(double r_m, double z_m, double tilt_rad, bool cull) {
  SplatSet set;
  set.positions_o = {Eigen::Vector3f(0.0f, 0.0f, static_cast<float>(z_m))};
  // Facing the camera (normal towards -z), tilted about x.
  set.normals_o = {Eigen::Vector3f(0.0f, static_cast<float>(std::sin(tilt_rad)),
                                   -static_cast<float>(std::cos(tilt_rad)))};
  set.radii_m = {static_cast<float>(r_m)};
  set.colours_rgb = {Eigen::Vector3f(1.0f, 1.0f, 1.0f)};
  set.ambient = 0.35f;
  set.cull_back_facing = cull;
  return set;
}

int labelledPixels(const RenderResult& r, uint8_t label) {
  return cv::countNonZero(r.labels == label);
}

// fx = fy = 300 px at 2 m: a 0.2 m disc projects to a 30 px radius, 2827 px^2 head-on. The
// equal-area hexagon has the disc's area; sampling at pixel centres changes each row's count by
// up to one pixel at either end, about +-60 px for the 60 rows, so 3 %. The principal point is
// off the pixel grid to avoid a systematic alignment of the hexagon's sides with it.
PinholeCamera splatCamera() { return PinholeCamera(300.0, 300.0, 49.3, 50.2, 100, 100); }
constexpr double kDiscPx = M_PI * 30.0 * 30.0;

TEST(OffscreenRenderer, SplatDiscSilhouetteHasTheDiscArea) {
  const PinholeCamera cam = splatCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  const int head_on = renderer.addSplats(oneDisc(0.2, 2.0, 0.0, true));
  const int tilted = renderer.addSplats(oneDisc(0.2, 2.0, M_PI / 3.0, true));
  const RenderView view{cam, SE3(), 0.05, 50.0};
  const double disc_px = kDiscPx;
  const RenderResult a = renderer.render(view, {{head_on, SE3(), 1.0f, 5}});
  EXPECT_NEAR(labelledPixels(a, 5), disc_px, 0.03 * disc_px);
  EXPECT_NEAR(a.depth_m.at<float>(50, 50), 2.0f, 1e-3);
  // Lit head-on by the headlight: full colour at the centre.
  EXPECT_EQ(a.bgr.at<cv::Vec3b>(49, 49), cv::Vec3b(255, 255, 255));

  // Tilted by 60 deg: an ellipse of half the area (depth varies across it: within a few percent),
  // shaded 0.35 + 0.65 |cos| with |cos| ~ 0.5 at the centre (the ray is the optical axis there).
  const RenderResult b = renderer.render(view, {{tilted, SE3(), 1.0f, 6}});
  EXPECT_NEAR(labelledPixels(b, 6), 0.5 * disc_px, 0.05 * 0.5 * disc_px);
  EXPECT_NEAR(b.bgr.at<cv::Vec3b>(49, 49)[1], 255.0 * (0.35 + 0.65 * 0.5), 3.0);
}

TEST(OffscreenRenderer, BackFacingSplatsAreCulledOnlyWhenAsked) {
  const PinholeCamera cam = splatCamera();
  OffscreenRenderer renderer(cam.width(), cam.height());
  SplatSet away = oneDisc(0.2, 2.0, 0.0, true);
  away.normals_o[0] = -away.normals_o[0];  // facing away from the camera
  SplatSet away_drawn = away;
  away_drawn.cull_back_facing = false;
  const int culled = renderer.addSplats(away);
  const int drawn = renderer.addSplats(away_drawn);
  const RenderView view{cam, SE3(), 0.05, 50.0};
  EXPECT_EQ(labelledPixels(renderer.render(view, {{culled, SE3(), 1.0f, 3}}), 3), 0);
  EXPECT_NEAR(labelledPixels(renderer.render(view, {{drawn, SE3(), 1.0f, 3}}), 3), kDiscPx,
              0.03 * kDiscPx);
}

TEST(OffscreenRenderer, SplatGridCoversItsSquare) {
  // 40 x 40 surfels 1 cm apart on the plane z = 2 m, radius 0.75 cm (discs overlap: no holes),
  // more than one chunk of the renderer's expansion buffer when repeated: a 0.4 m square seen
  // at 200 px/m... plus half a pixel of rim; the pose of the item moves it by 0.1 m in x.
  const PinholeCamera cam(200.0, 200.0, 49.5, 49.5, 100, 100);
  OffscreenRenderer renderer(cam.width(), cam.height());
  SplatSet set;
  for (int copy = 0; copy < 12; ++copy) {  // 19200 splats, the same square 12 times
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 40; ++j) {
        set.positions_o.emplace_back(-0.195f + 0.01f * i, -0.195f + 0.01f * j, 2.0f);
        set.normals_o.emplace_back(0.0f, 0.0f, -1.0f);
        set.radii_m.push_back(0.0075f);
        set.colours_rgb.emplace_back(0.2f, 0.4f, 0.6f);
      }
    }
  }
  const int grid = renderer.addSplats(set);
  const SE3 T_w_o(Quat::Identity(), Vec3(0.1, 0.0, 0.0));
  const RenderResult r = renderer.render({cam, SE3(), 0.05, 50.0}, {{grid, T_w_o, 1.0f, 9}});
  // Square side: 0.39 m between outer centres + 2 x 0.0075 m radius = 0.405 m -> 40.5 px.
  const double expected_px = 40.5 * 40.5;
  EXPECT_NEAR(labelledPixels(r, 9), expected_px, 0.04 * expected_px);
  // Shifted 0.1 m = 10 px right: columns left of u = 49.5 + 10 - 20.25 are empty.
  EXPECT_EQ(cv::countNonZero(r.labels(cv::Rect(0, 0, 38, 100))), 0);
  EXPECT_EQ(r.labels.at<uint8_t>(50, 60), 9);
  EXPECT_EQ(r.bgr.at<cv::Vec3b>(50, 60), cv::Vec3b(153, 102, 51));  // BGR of (0.2, 0.4, 0.6)
}

}  // namespace
}  // namespace ltlo::render
