#pragma once
/// Even spatial distribution of corners: a quadtree splits the image until it has about as many
/// occupied nodes as wanted features, then keeps the strongest corner of each node.
#include <vector>

#include <opencv2/core.hpp>

namespace ltlo::features {

/// Indices into `corners` of at most `target` corners spread over `area` (level pixels).
/// Deterministic: depends only on the corner list and its order.
std::vector<int> selectDistributed(const std::vector<cv::KeyPoint>& corners, const cv::Rect& area, int target);

}  // namespace ltlo::features
