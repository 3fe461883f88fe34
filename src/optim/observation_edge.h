#pragma once
// One reprojection edge of either kind (RGB-D or monocular), with what the outlier-rejection rounds
// of pose-only tracking and local BA need. Private to src/optim.
#include <sparse_opt/edge.h>

namespace ltlo::optim {

template <typename RgbdEdge, typename MonoEdge>
struct ReprojectionObservation {
  sparse_opt::EdgeBase* edge = nullptr;
  RgbdEdge* rgbd = nullptr;
  MonoEdge* mono = nullptr;
  double threshold = 0.0;  ///< chi2 gate (unweighted)

  // Unweighted chi2 at the current estimate and whether the point is in front of the camera.
  double unweightedChi2(bool* depth_positive) const {
    edge->computeError();
    if (rgbd != nullptr) {
      *depth_positive = rgbd->isDepthPositive();
      return rgbd->unweightedChi2();
    }
    *depth_positive = mono->isDepthPositive();
    return mono->unweightedChi2();
  }
  bool passes() const {
    bool depth_positive = false;
    const double chi2 = unweightedChi2(&depth_positive);
    return depth_positive && chi2 <= threshold;
  }
};

}  // namespace ltlo::optim
