// bench_segmentation: the segmentation kernels of the tracking thread against references in the
// same run (report the ratios; the machine's load cancels out).
//
//   BM_DepthKMeans/K        DepthKMeans on a generated 320x240 depth image (the base of VGA input):
//                           K = 24, 48, 64 (Seg.Clusters), 3 Lloyd iterations on the 80x60 samples,
//                           the assignment of all pixels with labels, counts and V_i.
//   BM_CvKmeansSamePoints   reference: cv::kmeans on all the same 320x240 points (3 iterations, one
//                           attempt, one thread), which gives labels only.
//   BM_DenseSolve           DenseSolver on a generated pushed-box pair (dense_solver_test.cc's scene)
//                           with the default schedule (state on levels 2-1) and the brightness change.
//   BM_DenseSolveClusters/K the same solve on K = 24, 48, 64 depth clusters (the cost of Seg.Clusters).
//   BM_DenseSolveNoBrightness  reference: the same solve with Seg.AffineBrightness 0 (Eq. 61 as it
//                           stands).
//   BM_DenseSolveFullSchedule  reference: the same solve without the early stop (Dense.StepTolerance 0:
//                           every level and alternation runs Dense.IterationsPerLevel steps).
//   BM_DenseSolveQvga       reference: the same solve with the state also on level 0 (Dense.FinestLevel 0).
//   BM_ImageTerm            the normal equations of the image term on level 1 (float lanes) ...
//   BM_ImageTermNaive       ... against a direct Eigen double 6x6 accumulation per residual.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "dense_kernels.h"
#include "ltlo/segmentation/dense_frame.h"
#include "ltlo/segmentation/dense_solver.h"
#include "ltlo/segmentation/depth_kmeans.h"
#include "segmentation/synthetic_depth.h"
#include "segmentation/synthetic_rgbd.h"

namespace ltlo::segmentation {
namespace {

const test::SyntheticDepth& depthScene() {
  static const test::SyntheticDepth depth = test::makeTwoPlanesAndBox(320, 240);
  return depth;
}

void BM_DepthKMeans(benchmark::State& state) {
  DepthKMeansOptions options;
  options.num_clusters = static_cast<int>(state.range(0));
  DepthKMeans kmeans{options};
  DepthClusters clusters;
  for (auto _ : state) {
    kmeans.cluster(depthScene().depth_m, depthScene().camera, &clusters);
    benchmark::DoNotOptimize(clusters.labels.data);
  }
}
BENCHMARK(BM_DepthKMeans)->Arg(24)->Arg(48)->Arg(64)->Unit(benchmark::kMillisecond);

void BM_CvKmeansSamePoints(benchmark::State& state) {
  cv::setNumThreads(1);
  const PinholeCamera& camera = depthScene().camera;
  std::vector<cv::Point3f> points;
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const float z = depthScene().depth_m.at<float>(v, u);
      if (z <= 0.0f) continue;
      points.emplace_back(static_cast<float>((u - camera.cx()) / camera.fx() * z),
                          static_cast<float>((v - camera.cy()) / camera.fy() * z), z);
    }
  }
  const cv::Mat samples(static_cast<int>(points.size()), 3, CV_32F, points.data());
  for (auto _ : state) {
    cv::theRNG().state = 1;
    cv::Mat labels, centres;
    cv::kmeans(samples, 24, labels, cv::TermCriteria(cv::TermCriteria::COUNT, 3, 0.0), 1, cv::KMEANS_RANDOM_CENTERS,
               centres);
    benchmark::DoNotOptimize(labels.data);
  }
  state.counters["points"] = static_cast<double>(points.size());
}
BENCHMARK(BM_CvKmeansSamePoints)->Unit(benchmark::kMillisecond);

/// A pushed box covering ~70 % of a VGA view, rigid with the camera, over one 30 Hz frame.
struct DensePair {
  DenseFrame previous, current;
  DepthClusters clusters;
  std::vector<double> previous_gamma;
  DensePrior prior;

  explicit DensePair(int finest_level, int num_clusters = DepthKMeansOptions().num_clusters) {
    const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
    const SE3 T_c_o(Quat::Identity(), Vec3(0.05, 0.15, 1.1));
    const SE3 T_w_c_b = SE3(so3ExpQuat(Vec3(0.0, 0.015, 0.0)), Vec3(0.008, 0.0, 0.028));
    test::BoxInWorld box;
    box.half_size_m = Vec3(0.35, 0.45, 0.3);
    DenseOptions dense;
    dense.finest_level = finest_level;
    const DenseFrameOptions options = DenseFrameOptions::from(SegmentationOptions(), dense);
    DepthKMeansOptions kmeans_options;
    kmeans_options.num_clusters = num_clusters;
    DepthKMeans kmeans{kmeans_options};
    auto prepare = [&](const SE3& T_w_c, DenseFrame* frame) {
      box.T_w_o = T_w_c * T_c_o;
      const test::RgbdFrame rgbd = test::renderRoom(camera, T_w_c, box);
      frame->build(rgbd.color_bgr, rgbd.depth_m, camera, options);
      const DenseLevel& base = frame->level(0);
      kmeans.cluster(base.depth_m,
                     PinholeCamera(base.camera.fx, base.camera.fy, base.camera.cx, base.camera.cy, base.camera.width,
                                   base.camera.height),
                     &clusters);
      frame->setLabels(clusters.labels, clusters.num_clusters);
    };
    prepare(SE3(), &previous);
    previous_gamma.assign(static_cast<std::size_t>(clusters.num_clusters) + 1, 1.0);
    prepare(T_w_c_b, &current);
    prior.kind = DensePrior::Kind::kRelativePose;
    prior.T_w_b_pred = T_w_c_b * SE3::exp((Vec6() << 0.002, 0.0, 0.0, 0.003, 0.0, 0.0).finished());
    prior.pose_information = Mat6::Identity() / (0.005 * 0.005);
  }
};

void denseSolve(benchmark::State& state, int finest_level, double step_tolerance_px, bool affine_brightness = true,
                int num_clusters = DepthKMeansOptions().num_clusters) {
  const DensePair pair(finest_level, num_clusters);
  DenseOptions dense;
  dense.finest_level = finest_level;
  dense.step_tolerance_px = step_tolerance_px;
  SegmentationOptions segmentation;
  segmentation.affine_brightness = affine_brightness;
  DenseSolver solver(DenseSolverOptions::from(segmentation, dense, LocalMappingOptions()));
  int steps = 0;
  for (auto _ : state) {
    const DenseResult result = solver.solve(pair.previous, pair.previous_gamma, pair.current, pair.clusters.edges, pair.prior);
    steps = result.gauss_newton_steps;
    benchmark::DoNotOptimize(result.gamma.data());
  }
  state.counters["gn_steps"] = steps;
}
void BM_DenseSolve(benchmark::State& state) { denseSolve(state, 1, DenseOptions().step_tolerance_px); }
void BM_DenseSolveNoBrightness(benchmark::State& state) {
  denseSolve(state, 1, DenseOptions().step_tolerance_px, /*affine_brightness=*/false);
}
void BM_DenseSolveFullSchedule(benchmark::State& state) { denseSolve(state, 1, 0.0); }
void BM_DenseSolveQvga(benchmark::State& state) { denseSolve(state, 0, DenseOptions().step_tolerance_px); }
void BM_DenseSolveClusters(benchmark::State& state) {
  denseSolve(state, 1, DenseOptions().step_tolerance_px, true, static_cast<int>(state.range(0)));
}
BENCHMARK(BM_DenseSolve)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DenseSolveNoBrightness)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DenseSolveFullSchedule)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DenseSolveQvga)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DenseSolveClusters)->Arg(24)->Arg(48)->Arg(64)->Unit(benchmark::kMillisecond);

const DensePair& levelOnePair() {
  static const DensePair pair(1);
  return pair;
}

void BM_ImageTerm(benchmark::State& state) {
  const DensePair& pair = levelOnePair();
  std::array<float, 256> gamma;
  gamma.fill(1.0f);
  detail::RowScratch rows;
  const detail::Warp warp;
  for (auto _ : state) {
    detail::ImageNormalEquations equations;
    detail::accumulateImageTerm(pair.previous.level(1), pair.current.level(1), warp, gamma.data(),
                                detail::ResidualParams(), &rows, &equations);
    benchmark::DoNotOptimize(equations.H.data());
  }
}
BENCHMARK(BM_ImageTerm)->Unit(benchmark::kMicrosecond);

// The same residuals and Jacobians (identity warp: rows from the previous frame's lookup at the
// current pixel), accumulated the direct way: H += w J J^T in double per residual.
void BM_ImageTermNaive(benchmark::State& state) {
  const DensePair& pair = levelOnePair();
  const DenseLevel& previous = pair.previous.level(1);
  const DenseLevel& current = pair.current.level(1);
  const detail::ResidualParams params;
  const double inv_c2 = 1.0 / (params.cauchy_c * params.cauchy_c);
  for (auto _ : state) {
    Mat6 H = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    for (std::size_t i = 0; i < current.pixel.size(); ++i) {
      const Vec3 p(current.x_m[i], current.y_m[i], current.z_m[i]);
      const Vec2 uv(previous.camera.fx * p.x() / p.z() + previous.camera.cx,
                    previous.camera.fy * p.y() / p.z() + previous.camera.cy);
      if (uv.x() < 0 || uv.y() < 0 || uv.x() >= previous.camera.width - 1 || uv.y() >= previous.camera.height - 1) continue;
      const int c = static_cast<int>(uv.x()), r = static_cast<int>(uv.y());
      const double fu = uv.x() - c, fv = uv.y() - r;
      Eigen::Matrix<double, 8, 1> s = Eigen::Matrix<double, 8, 1>::Zero();
      const double weights[4] = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
      const int offsets[4] = {0, 1, previous.camera.width, previous.camera.width + 1};
      for (int t = 0; t < 4; ++t) {
        const float* entry = &previous.lookup[(static_cast<std::size_t>(r) * previous.camera.width + c + offsets[t]) *
                                              kLookupChannels];
        for (int k = 0; k < 8; ++k) s(k) += weights[t] * entry[k];
      }
      Eigen::Matrix<double, 2, 6> J_uv;
      const double iz = 1.0 / p.z();
      Mat36 d_p;
      d_p << 0, p.z(), -p.y(), 1, 0, 0, -p.z(), 0, p.x(), 0, 1, 0, p.y(), -p.x(), 0, 0, 0, 1;
      Eigen::Matrix<double, 2, 3> d_uv;
      d_uv << previous.camera.fx * iz, 0, -previous.camera.fx * p.x() * iz * iz, 0, previous.camera.fy * iz,
          -previous.camera.fy * p.y() * iz * iz;
      J_uv = d_uv * d_p;
      const Vec6 J_I = (s(kLookupIu) * J_uv.row(0) + s(kLookupIv) * J_uv.row(1)).transpose();
      const double r_I = s(kLookupI) - current.intensity_at[i];
      const double aw = params.alpha_intensity * current.weight_I[i];
      const double w_I = aw * aw / (1.0 + aw * aw * r_I * r_I * inv_c2);
      H += w_I * J_I * J_I.transpose();
      b += w_I * J_I * r_I;
      if (s(kLookupValid) > 0.999) {
        const Vec6 J_D = (s(kLookupDu) * J_uv.row(0) + s(kLookupDv) * J_uv.row(1)).transpose() - d_p.row(2).transpose();
        const double r_D = s(kLookupD) - p.z();
        const double wd = current.weight_D[i];
        const double w_D = wd * wd / (1.0 + wd * wd * r_D * r_D * inv_c2);
        H += w_D * J_D * J_D.transpose();
        b += w_D * J_D * r_D;
      }
    }
    benchmark::DoNotOptimize(H.data());
    benchmark::DoNotOptimize(b.data());
  }
}
BENCHMARK(BM_ImageTermNaive)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ltlo::segmentation

BENCHMARK_MAIN();
