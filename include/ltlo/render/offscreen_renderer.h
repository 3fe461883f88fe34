#pragma once
/// Offscreen OpenGL renderer on OSMesa (software, no window, no GPU).
///
/// Renders textured or vertex-coloured triangle meshes, points and lines seen by a pinhole camera
/// and reads back colour (BGR), metric depth z (camera frame, metres) and a per-pixel 8-bit label
/// of the drawn item. The projection matches ltlo::PinholeCamera exactly: the centre of pixel
/// (u, v) (top-left pixel centre = (0, 0), v down) is where project() lands, and the rasteriser
/// samples at pixel centres. Legacy fixed-function GL (Mesa's OSMesa gives a 2.1+ compatibility
/// context); no lighting, so a surface looks the same from every view.
///
/// Not thread-safe: one renderer per thread; the OSMesa context is made current on the thread that
/// calls render(). Geometry is uploaded once (display lists) and drawn many times with poses.
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/core/lie.h"

namespace ltlo::render {

/// Triangle mesh in its own object frame o. `uvs` (texture coordinates, v down the image) are
/// used with `texture`; `colours_rgb` (0..1 per vertex, white when empty) multiply the texture
/// (baked shading) or are the colour of an untextured mesh.
struct Mesh {
  std::vector<Eigen::Vector3f> positions_o;
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3f> colours_rgb;
  std::vector<uint32_t> triangles;  ///< 3 vertex indices per triangle
  int texture = -1;                 ///< id from OffscreenRenderer::addTexture, -1 = none

  /// Appends another mesh's triangles (same texture assumed).
  void append(const Mesh& other);
};

/// Points drawn as screen-aligned squares of `size_px` (quick previews, sparse map points).
struct PointSet {
  std::vector<Eigen::Vector3f> positions_o;
  std::vector<Eigen::Vector3f> colours_rgb;  ///< optional, white when empty
  float size_px = 2.0f;
};

/// Line segments: positions_o[2k], positions_o[2k+1] per segment (trajectories, frusta).
struct LineSet {
  std::vector<Eigen::Vector3f> positions_o;
  std::vector<Eigen::Vector3f> colours_rgb;  ///< optional, one per vertex
  float width_px = 1.0f;
};

/// Oriented discs (surfel splats) as a triangle mesh: one `num_sides`-gon per surfel, in the
/// plane normal to normals_o[i], of radius radii_m[i], coloured colours_rgb[i].
Mesh makeSplatMesh(const std::vector<Eigen::Vector3f>& positions_o,
                   const std::vector<Eigen::Vector3f>& normals_o, const std::vector<float>& radii_m,
                   const std::vector<Eigen::Vector3f>& colours_rgb, int num_sides = 6);

/// Surfel splats kept compactly (about 40 bytes each) and expanded at draw time into oriented
/// discs: one hexagon of the disc's area per splat (radius scaled by sqrt(2 pi / (3 sqrt 3)) =
/// 1.0996), in the plane normal to normals_o[i]; a splat projected smaller than 2 px in radius
/// becomes a square of the disc's area (a third of the cost; the shape is not visible). Cheaper
/// in memory than makeSplatMesh for millions of splats, and shaded per view.
struct SplatSet {
  std::vector<Eigen::Vector3f> positions_o;
  std::vector<Eigen::Vector3f> normals_o;  ///< unit normals
  std::vector<float> radii_m;
  std::vector<Eigen::Vector3f> colours_rgb;  ///< 0..1
  /// Headlight shading by normal: colour * (ambient + (1 - ambient) |n . ray| / |ray|), ray from
  /// the viewer to the splat; 1 = unlit (flat colour).
  float ambient = 1.0f;
  /// Skip splats whose normal points away from the viewer (n . ray > 0): a room's inside then
  /// shows from outside, and surfels only ever seen from one side keep to it.
  bool cull_back_facing = false;
};

/// Axis-aligned box of the given full extents centred at the origin of its frame; each face
/// maps the whole texture once with `uv_scale` repeats per metre (0 = once per face).
Mesh makeBoxMesh(const Vec3& size_m, int texture, double uv_repeats_per_m = 0.0);

/// Closed cylinder along z, centred at the origin of its frame (z in [-length/2, length/2]), its
/// side a prism of `sides` flat faces (own vertices per face, so baked flat shading works) and two
/// caps. The side maps the texture once around (u) and along (v); each cap the texture's centre.
Mesh makeCylinderMesh(double radius_m, double length_m, int sides, int texture);

/// What to draw and how: one uploaded drawable at pose T_w_o.
struct DrawItem {
  int drawable = -1;  ///< id from addMesh/addPoints/addLines
  SE3 T_w_o;          ///< object pose in the world
  float gain = 1.0f;  ///< colour multiplier (exposure)
  uint8_t label = 0;  ///< written into RenderResult::labels where this item is visible
};

struct RenderView {
  PinholeCamera camera;  ///< must have the renderer's width and height
  SE3 T_c_w;             ///< world into camera
  double near_m = 0.05;  ///< clip planes (metres along the optical axis)
  double far_m = 50.0;
  Eigen::Vector3f background_rgb = Eigen::Vector3f::Zero();
};

struct RenderResult {
  cv::Mat bgr;      ///< CV_8UC3
  cv::Mat depth_m;  ///< CV_32F, z in the camera frame (metres), 0 where nothing was drawn
  cv::Mat labels;   ///< CV_8U, DrawItem::label of the visible surface, 0 for background
};

class OffscreenRenderer {
 public:
  /// Creates the OSMesa context and buffers; throws std::runtime_error when OSMesa fails.
  OffscreenRenderer(int width, int height);
  ~OffscreenRenderer();
  OffscreenRenderer(const OffscreenRenderer&) = delete;
  OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

  int width() const;
  int height() const;

  /// Uploads a CV_8UC3 BGR image as a mipmapped, repeating texture; returns its id.
  int addTexture(const cv::Mat& bgr);
  /// Upload geometry; each returns a drawable id for DrawItem.
  int addMesh(const Mesh& mesh);
  int addPoints(const PointSet& points);
  int addLines(const LineSet& lines);
  /// Stores the splats (moved in); they are expanded and shaded for each view in render().
  int addSplats(SplatSet splats);

  /// Deletes every drawable (meshes, points, lines, splats; textures stay): for scenes rebuilt per
  /// view such as the live viewer's map. Ids given before are invalid afterwards; new ones start
  /// at 0 again.
  void clearDrawables();

  /// Draws `items` (depth-tested) into the internal buffer and reads everything back.
  RenderResult render(const RenderView& view, const std::vector<DrawItem>& items);

  /// Column-major 4x4 OpenGL projection for `camera` acting on camera-frame points (x right,
  /// y down, z forward): window x = u + 0.5, window y = v + 0.5 (GL row v = image row v).
  static Eigen::Matrix4d projectionMatrix(const PinholeCamera& camera, double near_m, double far_m);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::render
