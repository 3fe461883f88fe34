#pragma once
/// The options of the three stages and the tracker's segmentation step, taken from the run's
/// Settings (private to system/; System's constructor builds the stages with them).
#include <memory>

#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/tracking/frame_segmenter.h"
#include "ltlo/tracking/tracker.h"

namespace bow {
class Vocabulary;
}
namespace ltlo {
class Undistorter;
}

namespace ltlo::system {

/// Keyframe and tracking settings; with the IMU and IMUInit.EarlyKeyFrames, a keyframe at least
/// every IMUInit.MinTime / (IMUInit.MinKeyFrames - 1) until the IMU is initialised.
tracking::TrackerOptions trackerOptions(const Settings& settings, bool use_imu);

/// Local mapping, segmentation and IMU-initialisation settings; `calib` is the calibration the frames
/// are built with (its camera gives the bf of every RGB-D edge).
mapping::LocalMapperOptions localMapperOptions(const Settings& settings, const SensorCalib& calib,
                                               std::shared_ptr<const bow::Vocabulary> vocabulary, bool use_imu);

/// Loop settings and the map-rejoin search of the tracker's re-acquisition (`tracker_options`); with
/// `use_imu`, Loop.WaitForImu.
loop::LoopCloserOptions loopCloserOptions(const Settings& settings, const tracking::TrackerOptions& tracker_options,
                                          bool use_imu);

/// The segmentation step the settings ask for (Seg.Enable, Seg.DenseInit), or the ground-truth
/// masks of the --oracle-masks ablation; its stages go to `timing`.
/// With a distorting lens each takes the images onto the ideal grid through `undistorter`.
std::unique_ptr<tracking::FrameSegmenter> makeSegmenter(const Settings& settings, bool oracle_masks, TimingStats* timing,
                                                        const std::shared_ptr<const Undistorter>& undistorter);

}  // namespace ltlo::system
