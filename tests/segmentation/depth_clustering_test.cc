#include "ltlo/segmentation/depth_clustering.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <opencv2/core.hpp>
#include <set>
#include <utility>

#include "ltlo/sim/simulator.h"
#include "segmentation/synthetic_depth.h"

namespace ltlo::segmentation {
namespace {

DepthClusteringOptions defaultOptions() { return DepthClusteringOptions{}; }

// Surfaces found under each cluster's pixels: surfaces[k][surface] = pixel count.
std::vector<std::map<int, int>> surfacesPerCluster(const ClusterMap& clusters,
                                                   const cv::Mat& surface) {
  std::vector<std::map<int, int>> result(clusters.num_clusters + 1);
  for (int v = 0; v < surface.rows; ++v) {
    for (int u = 0; u < surface.cols; ++u) {
      ++result[clusters.labels.at<int>(v, u)][surface.at<uint8_t>(v, u)];
    }
  }
  return result;
}

class TwoPlanesAndBox : public ::testing::TestWithParam<std::pair<int, int>> {};

// Clusters at 640x480 (subsampled by 2 to 320x240) and at 160x120 (clustered as is).
INSTANTIATE_TEST_SUITE_P(Sizes, TwoPlanesAndBox,
                         ::testing::Values(std::make_pair(640, 480), std::make_pair(160, 120)));

// Every cluster's pixels lie on one surface: none straddles the 1 m depth steps, and the
// no-depth label K holds exactly the pixels without depth.
TEST_P(TwoPlanesAndBox, ClustersStayOnOneSurfaceAndNoDepthIsLabelK) {
  const auto [width, height] = GetParam();
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(width, height);
  const ClusterMap clusters =
      DepthClustering(defaultOptions()).cluster(scene.depth_m, scene.camera);
  ASSERT_EQ(clusters.num_clusters, 24);
  ASSERT_EQ(clusters.labels.size(), scene.depth_m.size());
  ASSERT_EQ(clusters.labels.type(), CV_32S);
  const std::vector<std::map<int, int>> surfaces = surfacesPerCluster(clusters, scene.surface);
  for (int k = 0; k < clusters.num_clusters; ++k) {
    EXPECT_GT(clusters.pixel_counts[k], 0) << "cluster " << k << " is empty";
    EXPECT_EQ(surfaces[k].size(), 1u)
        << "cluster " << k << " spans " << surfaces[k].size() << " surfaces";
    EXPECT_EQ(surfaces[k].count(test::kNoDepth), 0u) << "cluster " << k;
  }
  const int num_no_depth = static_cast<int>(cv::countNonZero(scene.depth_m == 0.0f));
  EXPECT_EQ(surfaces[clusters.noDepthLabel()].size(), 1u);
  EXPECT_EQ(surfaces[clusters.noDepthLabel()].at(test::kNoDepth), num_no_depth);
  EXPECT_EQ(clusters.pixel_counts[clusters.noDepthLabel()], num_no_depth);
  int total = 0;
  for (const int count : clusters.pixel_counts) total += count;
  EXPECT_EQ(total, width * height);
}

// Each centroid lies on its cluster's surface: the box and near-plane depths exactly, the slanted
// far plane within its 2.85-3.15 m range.
TEST_P(TwoPlanesAndBox, CentroidsLieOnTheirSurfaces) {
  const auto [width, height] = GetParam();
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(width, height);
  const ClusterMap clusters =
      DepthClustering(defaultOptions()).cluster(scene.depth_m, scene.camera);
  const std::vector<std::map<int, int>> surfaces = surfacesPerCluster(clusters, scene.surface);
  ASSERT_EQ(clusters.centroids_c.size(), 24u);
  for (int k = 0; k < clusters.num_clusters; ++k) {
    const int surface = surfaces[k].begin()->first;
    const double z = clusters.centroids_c[k].z();
    if (surface == test::kBox) {
      EXPECT_NEAR(z, 1.0, 1e-4) << "cluster " << k;
    }
    if (surface == test::kNearPlane) {
      EXPECT_NEAR(z, 2.0, 1e-4) << "cluster " << k;
    }
    if (surface == test::kFarPlane) {
      EXPECT_GT(z, 2.85) << "cluster " << k;
      EXPECT_LT(z, 3.15) << "cluster " << k;
    }
  }
}

TEST_P(TwoPlanesAndBox, IsDeterministic) {
  const auto [width, height] = GetParam();
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(width, height);
  DepthClustering clustering(defaultOptions());
  const ClusterMap first = clustering.cluster(scene.depth_m, scene.camera);
  const ClusterMap second = clustering.cluster(scene.depth_m.clone(), scene.camera);
  EXPECT_EQ(cv::countNonZero(first.labels != second.labels), 0);
  ASSERT_EQ(first.centroids_c.size(), second.centroids_c.size());
  for (size_t k = 0; k < first.centroids_c.size(); ++k) {
    EXPECT_EQ(first.centroids_c[k], second.centroids_c[k]) << "cluster " << k;
  }
  ASSERT_EQ(first.edges.size(), second.edges.size());
  for (size_t e = 0; e < first.edges.size(); ++e) {
    EXPECT_EQ(first.edges[e].a, second.edges[e].a);
    EXPECT_EQ(first.edges[e].b, second.edges[e].b);
    EXPECT_EQ(first.edges[e].num_boundary_pairs, second.edges[e].num_boundary_pairs);
  }
}

// At 160x120 (no subsampling) the graph V is exactly: clusters on the same surface that share a
// 4-neighbour boundary, weighted by its number of pixel pairs; touching clusters across a depth
// step are not linked.
TEST(DepthClustering, ConnectivityLinksNeighboursOnOneSurfaceOnly) {
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(160, 120);
  const ClusterMap clusters =
      DepthClustering(defaultOptions()).cluster(scene.depth_m, scene.camera);
  const int K = clusters.num_clusters;
  std::map<std::pair<int, int>, int> same_surface_pairs;
  std::set<std::pair<int, int>> cross_surface_pairs;
  auto visit = [&](int u0, int v0, int u1, int v1) {
    const int a = clusters.labels.at<int>(v0, u0), b = clusters.labels.at<int>(v1, u1);
    if (a == b || a == K || b == K) return;
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    if (scene.surface.at<uint8_t>(v0, u0) == scene.surface.at<uint8_t>(v1, u1)) {
      ++same_surface_pairs[key];
    } else {
      cross_surface_pairs.insert(key);
    }
  };
  for (int v = 0; v < 120; ++v) {
    for (int u = 0; u < 160; ++u) {
      if (u + 1 < 160) visit(u, v, u + 1, v);
      if (v + 1 < 120) visit(u, v, u, v + 1);
    }
  }
  ASSERT_FALSE(
      cross_surface_pairs.empty());  // the scene does put clusters side by side across steps
  ASSERT_GE(same_surface_pairs.size(), 20u);
  EXPECT_EQ(clusters.edges.size(), same_surface_pairs.size());
  for (const ClusterEdge& edge : clusters.edges) {
    ASSERT_LT(edge.a, edge.b);
    const auto it = same_surface_pairs.find({edge.a, edge.b});
    ASSERT_NE(it, same_surface_pairs.end()) << "edge " << edge.a << "-" << edge.b;
    EXPECT_EQ(edge.num_boundary_pairs, it->second);
    EXPECT_TRUE(clusters.connected(edge.b, edge.a));
  }
  for (const auto& [a, b] : cross_surface_pairs) {
    if (same_surface_pairs.count({a, b}) == 0) {
      EXPECT_FALSE(clusters.connected(a, b)) << a << "-" << b;
    }
  }
}

// At 640x480 the graph is built at the 320x240 working resolution: still never across a depth
// step, and every cluster has a neighbour on its own surface (each surface holds several).
TEST(DepthClustering, SubsampledConnectivityNeverCrossesDepthSteps) {
  const test::SyntheticDepth scene = test::makeTwoPlanesAndBox(640, 480);
  const ClusterMap clusters =
      DepthClustering(defaultOptions()).cluster(scene.depth_m, scene.camera);
  const std::vector<std::map<int, int>> surfaces = surfacesPerCluster(clusters, scene.surface);
  for (const ClusterEdge& edge : clusters.edges) {
    EXPECT_EQ(surfaces[edge.a].begin()->first, surfaces[edge.b].begin()->first)
        << "edge " << edge.a << "-" << edge.b;
    EXPECT_GT(edge.num_boundary_pairs, 0);
  }
  for (int k = 0; k < clusters.num_clusters; ++k) {
    EXPECT_FALSE(clusters.neighbours(k).empty()) << "cluster " << k;
  }
}

// Fewer valid pixels than K: one cluster per valid pixel; none at all: everything is label 0 = K.
TEST(DepthClustering, FewValidPixelsGiveFewerClusters) {
  const PinholeCamera camera(100.0, 100.0, 31.5, 23.5, 64, 48);
  cv::Mat depth_m(48, 64, CV_32F, cv::Scalar(0.0f));
  DepthClustering clustering(defaultOptions());
  const ClusterMap empty = clustering.cluster(depth_m, camera);
  EXPECT_EQ(empty.num_clusters, 0);
  EXPECT_EQ(cv::countNonZero(empty.labels), 0);
  EXPECT_EQ(empty.pixel_counts, std::vector<int>{64 * 48});

  for (int i = 0; i < 5; ++i) depth_m.at<float>(10 + 5 * i, 3 + 11 * i) = 1.0f + i;
  depth_m.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();  // not a reading either
  const ClusterMap few = clustering.cluster(depth_m, camera);
  ASSERT_EQ(few.num_clusters, 5);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(few.pixel_counts[k], 1) << "cluster " << k;
  EXPECT_EQ(few.pixel_counts[5], 64 * 48 - 5);
  EXPECT_EQ(few.labelAt(0, 0), 5);
}

TEST(DepthClustering, OptionsComeFromSettings) {
  SegmentationOptions segmentation;
  segmentation.num_clusters = 16;
  segmentation.kmeans_iterations = 5;
  segmentation.max_neighbour_gap_m = 0.3;
  DenseOptions dense;
  dense.width = 160;
  dense.height = 120;
  const DepthClusteringOptions options = DepthClusteringOptions::from(segmentation, dense);
  EXPECT_EQ(options.num_clusters, 16);
  EXPECT_EQ(options.kmeans_iterations, 5);
  EXPECT_EQ(options.working_width, 160);
  EXPECT_EQ(options.working_height, 120);
  EXPECT_DOUBLE_EQ(options.gapThreshold(0.0), 0.02);
  EXPECT_DOUBLE_EQ(options.gapThreshold(1.0), 0.07);
  EXPECT_DOUBLE_EQ(options.gapThreshold(10.0), 0.3);  // capped by Seg.MaxNeighbourGap
}

// On noise-free simulated ltlo frames (160x120) with a box in view, clusters follow the
// ground-truth mask: >= 95 % of the pixels of a cluster larger than 1 % of the image share its
// majority mask value. Depth alone cannot always separate a box from static furniture it touches at
// the same depth (seed 3, frames 25-26: a box just behind a pillar whose side faces meet the box
// face without a gap), so one such cluster per frame and two in all (of about 140) are allowed;
// the pixel-weighted agreement of every frame must still reach 95 %.
TEST(DepthClustering, ClustersRespectSimulatedMaskBoundaries) {
  sim::SimOptions o;
  o.width_px = 160;
  o.height_px = 120;
  o.scenario = sim::Scenario::kLtlo;
  o.seed = 3;
  o.duration_s = 30.0;
  o.fps = 2.0;
  o.noise_free = true;
  sim::Simulator simulator(o);
  DepthClustering clustering(defaultOptions());
  int frames_checked = 0, clusters_checked = 0, clusters_mixed = 0;
  for (int i = 0; i < simulator.numFrames() && frames_checked < 6; ++i) {
    const sim::SimFrame frame = simulator.renderFrame(i);
    if (frame.dynamic_fraction < 0.1 || frame.dynamic_fraction > 0.8) continue;
    ++frames_checked;
    const ClusterMap clusters = clustering.cluster(frame.depth_m, simulator.camera());
    std::vector<int> dynamic_count(clusters.num_clusters + 1, 0);
    for (int v = 0; v < frame.mask.rows; ++v) {
      for (int u = 0; u < frame.mask.cols; ++u) {
        if (frame.mask.at<uint8_t>(v, u) != 0) ++dynamic_count[clusters.labels.at<int>(v, u)];
      }
    }
    const double min_size = 0.01 * frame.mask.total();
    int mixed = 0, agreeing = 0, total = 0;
    for (int k = 0; k < clusters.num_clusters; ++k) {
      const int size = clusters.pixel_counts[k];
      if (size <= min_size) continue;
      const int majority = std::max(dynamic_count[k], size - dynamic_count[k]);
      agreeing += majority;
      total += size;
      ++clusters_checked;
      if (majority < 0.95 * size) {
        ++mixed;
        std::printf("frame %d cluster %d: %d of %d pixels dynamic\n", i, k, dynamic_count[k], size);
      }
    }
    clusters_mixed += mixed;
    EXPECT_LE(mixed, 1) << "frame " << i;
    EXPECT_GE(agreeing, 0.95 * total) << "frame " << i;
    std::printf("frame %d: %.1f %% of pixels agree with their cluster's majority\n", i,
                100.0 * agreeing / total);
  }
  EXPECT_EQ(frames_checked, 6);
  EXPECT_LE(clusters_mixed, 2) << "of " << clusters_checked;
  std::printf("%d of %d clusters mixed\n", clusters_mixed, clusters_checked);
}

}  // namespace
}  // namespace ltlo::segmentation
