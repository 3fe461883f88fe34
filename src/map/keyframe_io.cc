// The keyframes section of the atlas file (atlas_file.h).
#include <string>

#include "atlas_file_access.h"
#include "atlas_file_sections.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/run_state_io.h"
#include "record_io.h"

namespace ltlo::map {

namespace {

void writeKeyFrame(const KeyFrame& kf, ByteWriter& out) {
  out.u64(kf.mapId().value);
  out.u64(kf.id().value);
  out.f64(kf.t_s());
  writeCamera(kf.camera(), out);
  out.se3(kf.T_b_c());
  writeFeatures(kf.keypoints(), kf.descriptors(), out);
  out.u64(kf.scaleFactors().size());
  for (const float s : kf.scaleFactors()) out.f32(s);
  for (int i = 0; i < kf.numKeypoints(); ++i) out.f32(kf.depth_m(i));
  writeSegmentation(kf.segmentationLayout(), out);
  out.f64(kf.staticThreshold());
  const std::vector<double> gamma = kf.gamma();
  out.u64(gamma.size());
  for (const double g : gamma) out.f64(g);
  out.se3(kf.T_w_b());
  out.vec3(kf.v_w_b());
  const imu::ImuBias bias = kf.bias();
  out.vec3(bias.b_g);
  out.vec3(bias.b_a);
  const std::optional<imu::Preintegrated> imu_from_previous = kf.imuFromPrevious();
  out.boolean(imu_from_previous.has_value());
  if (imu_from_previous) writePreintegration(*imu_from_previous, out);
}

std::shared_ptr<KeyFrame> readKeyFrame(ByteReader& in, const AtlasRestore& restore) {
  Map& map = readKnownMap(in, restore, "keyframe map");
  const std::uint64_t id_offset = in.fileOffset();
  const KeyFrameId id(in.u64("keyframe id"));
  if (!id.valid() || restore.keyframes.count(id) > 0)
    in.failAt(id_offset, "keyframe id invalid or repeated", std::to_string(id.value));
  const double t_s = in.finiteF64("keyframe time");
  const PinholeCamera camera = readCamera(in);
  const SE3 T_b_c = in.se3("T_b_c");
  features::OrbFeatures features = readFeatures(in);
  std::vector<float> scale_factors = readScaleFactors(in, features);
  std::vector<float> depths = readDepths(in, features.keypoints.size());
  ClusterSegmentation layout = readSegmentation(in);
  const double static_threshold = in.finiteF64("static threshold");
  const std::uint64_t gamma_offset = in.fileOffset();
  std::vector<double> gamma = readScores(in, "gamma");
  if (gamma.size() != layout.gamma.size()) {
    in.failAt(gamma_offset, "gamma for " + std::to_string(layout.gamma.size()) + " clusters",
              std::to_string(gamma.size()));
  }
  Frame frame(t_s, camera, T_b_c, std::move(features), std::move(depths), std::move(scale_factors));
  frame.setSegmentation(std::move(layout), static_threshold);
  frame.setPose_T_w_b(in.se3("T_w_b"));
  frame.setVelocity(in.vec3("v_w_b"));
  imu::ImuBias bias;
  bias.b_g = in.vec3("gyro bias");
  bias.b_a = in.vec3("accelerometer bias");
  frame.setBias(bias);
  if (in.boolean("has imu_from_previous")) frame.imu_from_last_keyframe = readPreintegration(in);
  auto kf = std::make_shared<KeyFrame>(id, map.id(), frame);
  kf->setGamma(std::move(gamma));  // the creation-time scores stay in the layout
  return kf;
}

}  // namespace

void writeKeyFramesSection(const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(snapshot.keyframe_ids.size());
  for (const AtlasSnapshot::MapEntry& entry : snapshot.maps) {
    for (const std::shared_ptr<KeyFrame>& kf : entry.keyframes) writeKeyFrame(*kf, out);
  }
}

void readKeyFramesSection(ByteReader& in, AtlasRestore& restore) {
  constexpr std::size_t kMinKeyFrameBytes = 200;  // ids, time, camera, poses, bias: far more
  const std::size_t n = in.count("keyframes", kMinKeyFrameBytes);
  for (std::size_t k = 0; k < n; ++k) {
    std::shared_ptr<KeyFrame> kf = readKeyFrame(in, restore);
    AtlasFileAccess::insert(*restore.maps.at(kf->mapId()), kf);
    restore.keyframes.emplace(kf->id(), std::move(kf));
  }
  in.expectEnd();
}

}  // namespace ltlo::map
