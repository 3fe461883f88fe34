// libFuzzer target: the trajectory readers (TUM text and EuRoC CSV), then what evaluate does with
// a trajectory: association with itself shifted in time, ATE (SE3 and Sim3 alignment) and RPE.
// Bad lines must give InputError; degenerate trajectories must not crash the metrics.
#include <cstddef>
#include <cstdint>
#include <sstream>

#include "fuzz_common.h"
#include "ltlo/core/errors.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "parsers.h"

namespace {

void evaluateAgainstItself(const ltlo::io::Trajectory& trajectory) {
  ltlo::io::Trajectory shifted = trajectory;
  for (ltlo::io::StampedPose& pose : shifted) pose.t_s += 1e-3;
  const ltlo::eval::MatchedTrajectories matched = ltlo::eval::associateTrajectories(trajectory, shifted, 0.02);
  if (matched.est.size() < 3) return;
  for (const bool with_scale : {false, true}) {
    const ltlo::eval::AteResult ate = ltlo::eval::computeAte(matched, with_scale);
    (void)ltlo::eval::computeRpe(matched, ate.S_gt_est);
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ltlo::fuzz::asText(data, size);
  try {
    std::istringstream in(text);
    evaluateAgainstItself(ltlo::io::detail::parseTumTrajectory(in, "est.txt"));
  } catch (const ltlo::InputError&) {
  }
  try {
    std::istringstream in(text);
    evaluateAgainstItself(ltlo::io::detail::parseEurocTrajectory(in, "est.csv"));
  } catch (const ltlo::InputError&) {
  }
  return 0;
}
