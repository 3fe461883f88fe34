// SE3 RANSAC on synthetic 3-D-3-D correspondences (fixed seeds).
#include "ltlo/place/se3_ransac.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace ltlo::place {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double rotationErrorDeg(const SE3& a, const SE3& b) { return (a.inverse() * b).log().head<3>().norm() * kRadToDeg; }
double translationError_m(const SE3& a, const SE3& b) { return (a.translation() - b.translation()).norm(); }

/// `num_inliers` points in front of a camera (depth 1..4 m) seen through T_a_b with noise
/// depthSigma_m(depth) / 10 per axis (0.3 to 5 mm), plus `num_outliers` random pairs.
std::vector<Correspondence3d> makeCorrespondences(std::mt19937& rng, const SE3& T_a_b, int num_inliers,
                                                  int num_outliers) {
  std::uniform_real_distribution<double> lateral(-1.5, 1.5), depth(1.0, 4.0);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::vector<Correspondence3d> out;
  for (int i = 0; i < num_inliers; ++i) {
    const Vec3 p_a(lateral(rng), lateral(rng), depth(rng));
    const double sigma = depthSigma_m(p_a.z());
    Correspondence3d c;
    c.p_a = p_a + (sigma / 10.0) * Vec3(unit(rng), unit(rng), unit(rng));
    c.p_b = T_a_b.inverse() * p_a;
    c.sigma_m = sigma;
    out.push_back(c);
  }
  for (int i = 0; i < num_outliers; ++i) {
    Correspondence3d c;
    c.p_a = Vec3(lateral(rng), lateral(rng), depth(rng));
    c.p_b = T_a_b.inverse() * Vec3(lateral(rng), lateral(rng), depth(rng));
    c.sigma_m = depthSigma_m(c.p_a.z());
    out.push_back(c);
  }
  std::shuffle(out.begin(), out.end(), rng);
  return out;
}

TEST(AlignRigid, ExactOnNoiseFreePoints) {
  const SE3 T_a_b = SE3::exp((Vec6() << 0.3, -0.2, 1.1, 0.5, -1.0, 2.0).finished());
  std::vector<Vec3> a, b;
  for (const Vec3& p : {Vec3(0, 0, 1), Vec3(1, 0, 2), Vec3(0, 1, 3), Vec3(1, 1, 1.5)}) {
    b.push_back(p);
    a.push_back(T_a_b * p);
  }
  const SE3 estimate = alignRigid(a, b);
  EXPECT_LT(rotationErrorDeg(estimate, T_a_b), 1e-8);
  EXPECT_LT(translationError_m(estimate, T_a_b), 1e-10);
}

TEST(Se3Ransac, RecoversPoseWith40PercentOutliers) {
  std::mt19937 rng(7);
  const SE3 T_a_b = SE3::exp((Vec6() << 0.05, 0.4, -0.1, 0.8, -0.3, 0.25).finished());
  const std::vector<Correspondence3d> correspondences = makeCorrespondences(rng, T_a_b, 120, 80);
  const Se3RansacResult result = estimateSe3Ransac(correspondences);
  ASSERT_TRUE(result.success);
  const double rot_deg = rotationErrorDeg(result.T_a_b, T_a_b);
  const double trans_m = translationError_m(result.T_a_b, T_a_b);
  std::printf("[ RANSAC   ] 120 inliers + 80 outliers: %d inliers found in %d iterations, error %.4f mm / %.5f deg\n",
              result.num_inliers, result.iterations, 1e3 * trans_m, rot_deg);
  EXPECT_LT(trans_m, 1e-3);
  EXPECT_LT(rot_deg, 0.05);
  EXPECT_GE(result.num_inliers, 110);
  EXPECT_LE(result.num_inliers, 125);  // a few outliers may fall within the gate by chance
}

TEST(Se3Ransac, DeterministicForAFixedSeed) {
  std::mt19937 rng(11);
  const SE3 T_a_b = SE3::exp((Vec6() << -0.2, 0.1, 0.3, 0.1, 0.2, -0.4).finished());
  const std::vector<Correspondence3d> correspondences = makeCorrespondences(rng, T_a_b, 60, 40);
  const Se3RansacResult first = estimateSe3Ransac(correspondences);
  const Se3RansacResult second = estimateSe3Ransac(correspondences);
  EXPECT_EQ(first.iterations, second.iterations);
  EXPECT_EQ(first.inliers, second.inliers);
  EXPECT_EQ(first.T_a_b.matrix(), second.T_a_b.matrix());
}

TEST(Se3Ransac, RejectsPureOutliers) {
  std::mt19937 rng(3);
  const std::vector<Correspondence3d> correspondences = makeCorrespondences(rng, SE3(), 0, 200);
  const Se3RansacResult result = estimateSe3Ransac(correspondences);
  std::printf("[ RANSAC   ] 200 random pairs: best consensus %d (min 20)\n", result.num_inliers);
  EXPECT_FALSE(result.success);
  EXPECT_LT(result.num_inliers, 20);
}

TEST(Se3Ransac, RejectsTooFewCorrespondences) {
  std::mt19937 rng(5);
  const std::vector<Correspondence3d> correspondences = makeCorrespondences(rng, SE3(), 10, 0);
  EXPECT_FALSE(estimateSe3Ransac(correspondences).success);
}

}  // namespace
}  // namespace ltlo::place
