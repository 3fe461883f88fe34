#pragma once
/// Grid of keypoint indices over the image for search by projection. Unlike
/// features::KeypointGrid it keeps no pointer to the keypoints (queries take them), so the Frame
/// and KeyFrame that own one stay copyable.
#include <vector>

#include "ltlo/features/orb_extractor.h"

namespace ltlo::map {

/// Immutable after construction; const queries are thread-safe.
class GridIndex {
 public:
  GridIndex() = default;
  /// Buckets `keypoints` (level-0 pixels) of a width_px x height_px image into cells of cell_px.
  GridIndex(const std::vector<features::Keypoint>& keypoints, int width_px, int height_px, float cell_px = 16.0f);

  /// Indices of the keypoints (the same vector given to the constructor) within radius_px
  /// (Chebyshev window) of (x_px, y_px) whose octave is in [min_octave, max_octave]
  /// (max_octave < 0: no upper bound), in increasing index order.
  std::vector<int> featuresInArea(const std::vector<features::Keypoint>& keypoints, float x_px, float y_px,
                                  float radius_px, int min_octave = 0, int max_octave = -1) const;
  /// The same into *found (cleared first; its capacity is reused across queries).
  void featuresInArea(const std::vector<features::Keypoint>& keypoints, float x_px, float y_px, float radius_px,
                      int min_octave, int max_octave, std::vector<int>* found) const;

 private:
  int cols_ = 0;
  int rows_ = 0;
  float inv_cell_ = 1.0f;
  /// The cells, row-major, as one array: cell c holds cell_items_[cell_start_[c] .. cell_start_[c + 1])
  /// in increasing index order. Two allocations per grid (a frame builds one per image) and ~11 KB for
  /// 1500 keypoints at VGA, where a vector per cell took ~45 KB and a few hundred allocations. Both
  /// empty without keypoints (a culled keyframe's stand-in): every query finds nothing.
  std::vector<int> cell_start_;
  std::vector<int> cell_items_;
};

}  // namespace ltlo::map
