#pragma once
/// Trajectory accuracy after Sturm et al. (TUM RGB-D benchmark) and thesis ch. 2.3: timestamp
/// association, Umeyama alignment (SE3, optionally Sim3), ATE (Eq. 14) and consecutive-frame RPE
/// (Eqs. 12-13). Poses are T_world_camera; errors in metres and degrees.
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/io/trajectory_io.h"

namespace ltlo::eval {

/// Summary of a list of non-negative errors. All zero when count == 0.
struct ErrorStats {
  int count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;  ///< middle value, mean of the two middle values for an even count
  double min = 0.0;
  double max = 0.0;
};
ErrorStats computeErrorStats(std::vector<double> errors);

/// Ground-truth and estimated poses paired by timestamp: gt[k] and est[k] belong together.
struct MatchedTrajectories {
  io::Trajectory gt;
  io::Trajectory est;
};

/// Pairs poses whose timestamps differ by at most max_dt_s (io::associateTimestamps: nearest
/// first, one-to-one), in time order.
MatchedTrajectories associateTrajectories(const io::Trajectory& gt, const io::Trajectory& est,
                                          double max_dt_s = 0.02);

/// Umeyama (1991) least squares: the similarity S_gt_est minimising sum |p_gt - S p_est|^2, with
/// scale fixed to 1 unless with_scale. Needs at least 3 non-collinear points for a unique
/// rotation (asserts at least 1 point and equal counts).
Sim3 umeyamaAlignment(const std::vector<Vec3>& p_est, const std::vector<Vec3>& p_gt,
                      bool with_scale);

/// Absolute trajectory error: translation error |t_gt - t(S_gt_est T_est)| per matched pose.
struct AteResult {
  Sim3 S_gt_est;       ///< alignment applied to the estimate
  ErrorStats error_m;  ///< per-pose translation errors (m)
};
AteResult computeAte(const MatchedTrajectories& matched, bool with_scale);
/// The same with a given alignment instead of the best one: a run in another run's world frame
/// (a loaded atlas) is measured with the alignment of that earlier run to the ground truth, so
/// whatever it got wrong in placing itself in that world counts.
AteResult computeAteFixed(const MatchedTrajectories& matched, const Sim3& S_gt_est);

/// Relative pose error over consecutive matched poses i, i+1:
///   E_i = (Q_i^-1 Q_{i+1})^-1 (P_i^-1 P_{i+1}),  Q ground truth, P aligned estimate,
/// translation |trans(E_i)| and rotation angle(E_i); per second divides by the ground-truth dt.
struct RpeResult {
  ErrorStats trans_m_frame;
  ErrorStats trans_m_s;
  ErrorStats rot_deg_frame;
  ErrorStats rot_deg_s;
};
/// The estimate is mapped by S_gt_est first (only its scale changes the result).
RpeResult computeRpe(const MatchedTrajectories& matched, const Sim3& S_gt_est = Sim3());

}  // namespace ltlo::eval
