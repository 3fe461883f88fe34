#pragma once
/// Records shared by the atlas file's keyframes section and the run state's frames (private to
/// ltlo_map; the public records are in ltlo/map/run_state_io.h): camera, 8/16-bit images, the
/// cluster segmentation, ORB features with their pyramid and depths. Every reader checks what the
/// live code would assert (ranges, sizes) and fails naming the field and value.
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/features/orb_extractor.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/map/cluster_segmentation.h"

namespace ltlo::map {

// Sizes that no real camera or segmentation reaches; larger values are a damaged file (and would
// drive the grid's and the images' allocations).
inline constexpr std::int32_t kMaxImageSide = 1 << 15;
// The camera's image size sets the keypoint grid's cell count (16 px cells) before any keypoint
// is read: at 8192 px a side that is 6 MB per keyframe, so a small file cannot ask for much.
inline constexpr std::int32_t kMaxCameraSide = 1 << 13;
inline constexpr std::int32_t kMaxScale = 1 << 10;
inline constexpr std::size_t kMaxPyramidLevels = 64;
inline constexpr std::size_t kMaxClusters = 256;                   // 8-bit labels
inline constexpr std::size_t kKeypointBytes = 4 * 4 + 4 + 32 + 4;  // keypoint, descriptor, depth

void writeCamera(const PinholeCamera& camera, ByteWriter& out);
PinholeCamera readCamera(ByteReader& in);

/// CV_8U (element_bytes 1) or CV_16U (2); rows = cols = 0 is the empty image.
void writeImage(const cv::Mat& image, int element_bytes, ByteWriter& out);
cv::Mat readImage(ByteReader& in, int element_bytes, const char* what);

/// Scores in [0, 1], 1 to 256 of them.
std::vector<double> readScores(ByteReader& in, const char* what);
void writeSegmentation(const ClusterSegmentation& segmentation, ByteWriter& out);
/// Everything ClusterSegmentation::validate() asserts is checked here first, as file errors.
ClusterSegmentation readSegmentation(ByteReader& in);

/// Keypoints (count first) then their descriptors.
void writeFeatures(const std::vector<features::Keypoint>& keypoints,
                   const std::vector<features::Descriptor>& descriptors, ByteWriter& out);
features::OrbFeatures readFeatures(ByteReader& in);
std::vector<float> readScaleFactors(ByteReader& in, const features::OrbFeatures& features);
/// `n` keypoint depths (m, >= 0).
std::vector<float> readDepths(ByteReader& in, std::size_t n);

}  // namespace ltlo::map
