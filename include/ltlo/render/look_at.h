#pragma once
/// The pose of a virtual camera (x right, y down, z forward) for rendered views: the reconstruction's
/// snapshots and the live viewer's 3-D panel.
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::render {

/// T_c_w of a camera at `eye_w` looking at `target_w` with `up_w` up in the image (any up not
/// parallel to the viewing direction; a parallel one picks an arbitrary roll).
SE3 lookAt(const Vec3& eye_w, const Vec3& target_w, const Vec3& up_w);

}  // namespace ltlo::render
