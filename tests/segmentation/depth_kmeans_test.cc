// DepthKMeans (depth_kmeans.h): clusters stay on one surface, pixels without depth get label K, the
// pixel counts and V_i come out of the same pass, V_i never crosses a depth step or a crease, and
// on simulated frames the clusters follow the ground-truth mask.
#include "ltlo/segmentation/depth_kmeans.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>

#include <opencv2/core.hpp>

#include "ltlo/sim/simulator.h"
#include "segmentation/synthetic_depth.h"

namespace ltlo::segmentation {
namespace {

// Surfaces found under each cluster's pixels: surfaces[k][surface] = pixel count.
std::vector<std::map<int, int>> surfacesPerCluster(const DepthClusters& clusters, const cv::Mat& surface) {
  std::vector<std::map<int, int>> result(static_cast<std::size_t>(clusters.num_clusters) + 1);
  for (int v = 0; v < surface.rows; ++v) {
    for (int u = 0; u < surface.cols; ++u) ++result[clusters.labels.at<std::uint8_t>(v, u)][surface.at<std::uint8_t>(v, u)];
  }
  return result;
}

DepthClusters clusterScene(const test::SyntheticDepth& scene, DepthKMeansOptions options = {}) {
  DepthClusters clusters;
  DepthKMeans(options).cluster(scene.depth_m, scene.camera, &clusters);
  return clusters;
}

// 320x240 (the working resolution of VGA input): 8-bit labels, every cluster on one surface (none
// straddles the 1 m depth steps), label K exactly on the pixels without depth, counts that add up.
TEST(DepthKMeans, ClustersStayOnOneSurfaceAndNoDepthIsLabelK) {
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(320, 240);
  const DepthClusters clusters = clusterScene(scene);
  ASSERT_EQ(clusters.num_clusters, DepthKMeansOptions().num_clusters);
  ASSERT_EQ(clusters.labels.type(), CV_8U);
  ASSERT_EQ(clusters.labels.size(), scene.depth_m.size());
  const std::vector<std::map<int, int>> surfaces = surfacesPerCluster(clusters, scene.surface);
  for (int k = 0; k < clusters.num_clusters; ++k) {
    EXPECT_GT(clusters.pixel_counts[k], 0) << "cluster " << k << " is empty";
    EXPECT_EQ(surfaces[k].size(), 1u) << "cluster " << k << " spans " << surfaces[k].size() << " surfaces";
    EXPECT_EQ(surfaces[k].count(test::kNoDepth), 0u) << "cluster " << k;
  }
  const int num_no_depth = cv::countNonZero(scene.depth_m == 0.0f);
  EXPECT_EQ(surfaces[24].size(), 1u);
  EXPECT_EQ(surfaces[24].at(test::kNoDepth), num_no_depth);
  EXPECT_EQ(clusters.pixel_counts[24], num_no_depth);
  int total = 0;
  for (int k = 0; k <= 24; ++k) {
    total += clusters.pixel_counts[k];
    EXPECT_EQ(clusters.pixel_counts[k], cv::countNonZero(clusters.labels == k)) << "cluster " << k;
  }
  EXPECT_EQ(total, 320 * 240);
  ASSERT_EQ(clusters.centroids_c.size(), 24u);
  for (int k = 0; k < 24; ++k) {
    const int surface = surfaces[k].begin()->first;
    const double z = clusters.centroids_c[k].z();
    if (surface == test::kBox) {
      EXPECT_NEAR(z, 1.0, 1e-4) << "cluster " << k;
    } else if (surface == test::kNearPlane) {
      EXPECT_NEAR(z, 2.0, 1e-4) << "cluster " << k;
    } else {
      EXPECT_TRUE(z > 2.85 && z < 3.15) << "cluster " << k << " at " << z;
    }
  }
}

// V_i is exactly the set of cluster pairs that share a 4-neighbour boundary on the same surface,
// each weighted by its number of boundary pixel pairs; clusters side by side across a depth step
// are not linked.
TEST(DepthKMeans, ConnectivityLinksNeighboursOnOneSurfaceOnly) {
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(320, 240);
  const DepthClusters clusters = clusterScene(scene);
  const int K = clusters.num_clusters;
  std::map<std::pair<int, int>, int> same_surface_pairs;
  std::set<std::pair<int, int>> cross_surface_pairs;
  auto visit = [&](int u0, int v0, int u1, int v1) {
    const int a = clusters.labels.at<std::uint8_t>(v0, u0), b = clusters.labels.at<std::uint8_t>(v1, u1);
    if (a == b || a == K || b == K) return;
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    if (scene.surface.at<std::uint8_t>(v0, u0) == scene.surface.at<std::uint8_t>(v1, u1)) {
      ++same_surface_pairs[key];
    } else {
      cross_surface_pairs.insert(key);
    }
  };
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      if (u + 1 < 320) visit(u, v, u + 1, v);
      if (v + 1 < 240) visit(u, v, u, v + 1);
    }
  }
  ASSERT_FALSE(cross_surface_pairs.empty());  // the scene does put clusters side by side across steps
  ASSERT_GE(same_surface_pairs.size(), 20u);
  EXPECT_EQ(clusters.edges.size(), same_surface_pairs.size());
  for (const ClusterEdge& edge : clusters.edges) {
    ASSERT_LT(edge.a, edge.b);
    const auto it = same_surface_pairs.find({edge.a, edge.b});
    ASSERT_NE(it, same_surface_pairs.end()) << "edge " << edge.a << "-" << edge.b;
    EXPECT_EQ(edge.num_boundary_pairs, it->second);
  }
}

// Two planes meeting along a vertical fold (a wall corner seen from inside, 90 degrees): the depth
// is continuous across the fold, so only the crease test keeps V_i from linking the two walls. With
// K = 4 the clusters are the quadrants: top and bottom on one wall stay linked, left and right not;
// without the crease test the fold links them.
TEST(DepthKMeans, CreaseBetweenTwoWallsIsNotAnEdge) {
  test::SyntheticDepth scene;
  const int w = 320, h = 240;
  const double f = 262.5;
  scene.camera = PinholeCamera(f, f, 159.5, 119.5, w, h);
  scene.depth_m = cv::Mat(h, w, CV_32F, cv::Scalar(0.0f));
  scene.surface = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  // Walls x + z = 2.5 (left) and z - x = 2.5 (right), meeting at x = 0, z = 2.5.
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const double x = (u - 159.5) / f;
      const bool left = x < 0.0;
      scene.depth_m.at<float>(v, u) = static_cast<float>(2.5 / (1.0 + std::abs(x)));
      scene.surface.at<std::uint8_t>(v, u) = left ? 1 : 2;
    }
  }
  DepthKMeansOptions options;
  options.num_clusters = 4;
  const DepthClusters clusters = clusterScene(scene, options);
  const std::vector<std::map<int, int>> surfaces = surfacesPerCluster(clusters, scene.surface);
  ASSERT_EQ(clusters.num_clusters, 4);
  int same_wall = 0;
  // The 4 px sample grid is not symmetric about the fold: a few columns of pixels may join the
  // other wall's cluster. Each cluster is named after its wall (>= 95 % of its pixels).
  std::vector<int> wall(4);
  for (int k = 0; k < 4; ++k) {
    const int on_left = surfaces[k].count(1) ? surfaces[k].at(1) : 0;
    const double left_share = static_cast<double>(on_left) / clusters.pixel_counts[k];
    ASSERT_TRUE(left_share >= 0.95 || left_share <= 0.05) << "cluster " << k << ": " << left_share << " on the left wall";
    wall[k] = left_share >= 0.95 ? 1 : 2;
  }
  for (const ClusterEdge& edge : clusters.edges) {
    const int a = wall[edge.a], b = wall[edge.b];
    EXPECT_EQ(a, b) << "clusters on the two walls linked: " << edge.a << "-" << edge.b;
    same_wall += a == b;
  }
  EXPECT_EQ(same_wall, 2);
  options.max_crease_angle_rad = M_PI;
  EXPECT_EQ(clusterScene(scene, options).edges.size(), 4u);  // the fold links left and right too
}

// Same input, same output (the worker relies on it for reproducible runs); reused buffers too.
TEST(DepthKMeans, IsDeterministicWithReusedBuffers) {
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(320, 240);
  DepthKMeans kmeans{DepthKMeansOptions{}};
  DepthClusters first, second;
  kmeans.cluster(scene.depth_m, scene.camera, &first);
  const test::SyntheticDepth other = test::makeTwoPlanesAndBox(320, 240);
  kmeans.cluster(other.depth_m.clone(), other.camera, &second);
  EXPECT_EQ(cv::countNonZero(first.labels != second.labels), 0);
  EXPECT_EQ(first.pixel_counts, second.pixel_counts);
  ASSERT_EQ(first.edges.size(), second.edges.size());
  for (std::size_t e = 0; e < first.edges.size(); ++e) {
    EXPECT_EQ(first.edges[e].a, second.edges[e].a);
    EXPECT_EQ(first.edges[e].b, second.edges[e].b);
    EXPECT_EQ(first.edges[e].num_boundary_pairs, second.edges[e].num_boundary_pairs);
  }
}

// Fewer pixels with depth than K: one cluster per such pixel; none at all: everything is label 0 = K.
TEST(DepthKMeans, FewValidPixelsGiveFewerClusters) {
  const PinholeCamera camera(100.0, 100.0, 31.5, 23.5, 64, 48);
  cv::Mat depth_m(48, 64, CV_32F, cv::Scalar(0.0f));
  DepthKMeans kmeans{DepthKMeansOptions{}};
  DepthClusters empty;
  kmeans.cluster(depth_m, camera, &empty);
  EXPECT_EQ(empty.num_clusters, 0);
  EXPECT_EQ(cv::countNonZero(empty.labels), 0);
  EXPECT_EQ(empty.pixel_counts, std::vector<int>{64 * 48});

  for (int i = 0; i < 5; ++i) depth_m.at<float>(10 + 5 * i, 3 + 11 * i) = 1.0f + i;
  depth_m.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();  // not a reading either
  DepthClusters few;
  kmeans.cluster(depth_m, camera, &few);
  ASSERT_EQ(few.num_clusters, 5);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(few.pixel_counts[k], 1) << "cluster " << k;
  EXPECT_EQ(few.pixel_counts[5], 64 * 48 - 5);
  EXPECT_EQ(few.labels.at<std::uint8_t>(0, 0), 5);
}

TEST(DepthKMeans, OptionsComeFromSettings) {
  SegmentationOptions segmentation;
  segmentation.num_clusters = 16;
  segmentation.kmeans_iterations = 5;
  segmentation.max_neighbour_gap_m = 0.3;
  const DepthKMeansOptions options = DepthKMeansOptions::from(segmentation);
  EXPECT_EQ(options.num_clusters, 16);
  EXPECT_EQ(options.kmeans_iterations, 5);
  EXPECT_DOUBLE_EQ(options.gapThreshold(0.0), 0.02);
  EXPECT_DOUBLE_EQ(options.gapThreshold(1.0), 0.07);
  EXPECT_DOUBLE_EQ(options.gapThreshold(10.0), 0.3);  // capped by Seg.MaxNeighbourGap
}

// On noise-free simulated ltlo frames (160x120) with a box in view, clusters follow the
// ground-truth mask: of the pixels of clusters larger than 1 % of the image, >= 95 % share their
// cluster's majority mask value over the frames, >= 88 % on every frame. Depth alone cannot always
// separate a box from static furniture it touches at the same depth (seed 3, frames 25-28: a box
// just behind a pillar whose side faces meet the box face without a gap); the removed
// surface-break splitting kept 95 % there, but on whole 45 s sequences its clusters' best possible
// static IoU was lower than these (ltlo seed 1: 0.970 against 0.972, seed 2: 0.957 against 0.967).
TEST(DepthKMeans, ClustersRespectSimulatedMaskBoundaries) {
  sim::SimOptions o;
  o.width_px = 160;
  o.height_px = 120;
  o.scenario = sim::Scenario::kLtlo;
  o.seed = 3;
  o.duration_s = 30.0;
  o.fps = 2.0;
  o.noise_free = true;
  sim::Simulator simulator(o);
  DepthKMeans kmeans{DepthKMeansOptions{}};
  int frames_checked = 0;
  long agreeing_all = 0, total_all = 0;
  for (int i = 0; i < simulator.numFrames() && frames_checked < 6; ++i) {
    const sim::SimFrame frame = simulator.renderFrame(i);
    if (frame.dynamic_fraction < 0.1 || frame.dynamic_fraction > 0.8) continue;
    ++frames_checked;
    DepthClusters clusters;
    kmeans.cluster(frame.depth_m, simulator.camera(), &clusters);
    std::vector<int> dynamic_count(static_cast<std::size_t>(clusters.num_clusters) + 1, 0);
    for (int v = 0; v < frame.mask.rows; ++v) {
      for (int u = 0; u < frame.mask.cols; ++u) {
        if (frame.mask.at<std::uint8_t>(v, u) != 0) ++dynamic_count[clusters.labels.at<std::uint8_t>(v, u)];
      }
    }
    const double min_size = 0.01 * static_cast<double>(frame.mask.total());
    int agreeing = 0, total = 0;
    for (int k = 0; k < clusters.num_clusters; ++k) {
      const int size = clusters.pixel_counts[k];
      if (size <= min_size) continue;
      agreeing += std::max(dynamic_count[k], size - dynamic_count[k]);
      total += size;
    }
    EXPECT_GE(agreeing, 0.88 * total) << "frame " << i;
    agreeing_all += agreeing;
    total_all += total;
  }
  EXPECT_EQ(frames_checked, 6);
  EXPECT_GE(agreeing_all, 0.95 * total_all);
}

}  // namespace
}  // namespace ltlo::segmentation
