#include "ltlo/render/offscreen_renderer.h"

#include <GL/gl.h>
#include <GL/osmesa.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "ltlo/core/assert.h"

namespace ltlo::render {

void Mesh::append(const Mesh& other) {
  const uint32_t offset = static_cast<uint32_t>(positions_o.size());
  positions_o.insert(positions_o.end(), other.positions_o.begin(), other.positions_o.end());
  uvs.insert(uvs.end(), other.uvs.begin(), other.uvs.end());
  colours_rgb.insert(colours_rgb.end(), other.colours_rgb.begin(), other.colours_rgb.end());
  for (uint32_t index : other.triangles) triangles.push_back(index + offset);
}

Mesh makeSplatMesh(const std::vector<Eigen::Vector3f>& positions_o,
                   const std::vector<Eigen::Vector3f>& normals_o, const std::vector<float>& radii_m,
                   const std::vector<Eigen::Vector3f>& colours_rgb, int num_sides) {
  LTLO_ASSERT(normals_o.size() == positions_o.size() && radii_m.size() == positions_o.size() &&
                  colours_rgb.size() == positions_o.size(),
              "makeSplatMesh: sizes differ");
  LTLO_ASSERT(num_sides >= 3, "makeSplatMesh: num_sides = " << num_sides);
  Mesh mesh;
  mesh.positions_o.reserve(positions_o.size() * (num_sides + 1));
  for (size_t i = 0; i < positions_o.size(); ++i) {
    const Eigen::Vector3f n = normals_o[i].normalized();
    // Any unit vector orthogonal to n, then the third axis of the disc frame.
    const Eigen::Vector3f helper =
        std::abs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
    const Eigen::Vector3f e1 = n.cross(helper).normalized();
    const Eigen::Vector3f e2 = n.cross(e1);
    const uint32_t centre = static_cast<uint32_t>(mesh.positions_o.size());
    mesh.positions_o.push_back(positions_o[i]);
    mesh.colours_rgb.push_back(colours_rgb[i]);
    for (int k = 0; k < num_sides; ++k) {
      const float angle = 2.0f * static_cast<float>(M_PI) * k / num_sides;
      mesh.positions_o.push_back(positions_o[i] +
                                 radii_m[i] * (std::cos(angle) * e1 + std::sin(angle) * e2));
      mesh.colours_rgb.push_back(colours_rgb[i]);
      const uint32_t next = centre + 1 + static_cast<uint32_t>((k + 1) % num_sides);
      mesh.triangles.insert(mesh.triangles.end(), {centre, centre + 1 + k, next});
    }
  }
  return mesh;
}

Mesh makeBoxMesh(const Vec3& size_m, int texture, double uv_repeats_per_m) {
  Mesh mesh;
  mesh.texture = texture;
  const Eigen::Vector3f h = (0.5 * size_m).cast<float>();
  // Each face: centre axis (sign * axis), two in-plane axes (a, b) spanning it.
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {-1, 1}) {
      const int a = (axis + 1) % 3;
      const int b = (axis + 2) % 3;
      const uint32_t base = static_cast<uint32_t>(mesh.positions_o.size());
      const float corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (const auto& c : corners) {
        Eigen::Vector3f p;
        p[axis] = sign * h[axis];
        p[a] = c[0] * h[a];
        p[b] = c[1] * h[b];
        mesh.positions_o.push_back(p);
        const float su = uv_repeats_per_m > 0 ? static_cast<float>(2 * h[a] * uv_repeats_per_m) : 1;
        const float sv = uv_repeats_per_m > 0 ? static_cast<float>(2 * h[b] * uv_repeats_per_m) : 1;
        mesh.uvs.emplace_back(0.5f * (c[0] + 1) * su, 0.5f * (1 - c[1]) * sv);
      }
      mesh.triangles.insert(mesh.triangles.end(),
                            {base, base + 1, base + 2, base, base + 2, base + 3});
    }
  }
  return mesh;
}

Mesh makeCylinderMesh(double radius_m, double length_m, int sides, int texture) {
  LTLO_ASSERT(sides >= 3 && radius_m > 0 && length_m > 0, "cylinder " << radius_m << " x " << length_m);
  Mesh mesh;
  mesh.texture = texture;
  const float r = static_cast<float>(radius_m), h = static_cast<float>(0.5 * length_m);
  auto corner = [&](int k) {
    const double a = 2.0 * M_PI * k / sides;
    return Eigen::Vector2f(r * static_cast<float>(std::cos(a)), r * static_cast<float>(std::sin(a)));
  };
  for (int k = 0; k < sides; ++k) {  // side faces
    const Eigen::Vector2f a = corner(k), b = corner(k + 1);
    const float u0 = static_cast<float>(k) / sides, u1 = static_cast<float>(k + 1) / sides;
    const uint32_t base = static_cast<uint32_t>(mesh.positions_o.size());
    mesh.positions_o.insert(mesh.positions_o.end(), {{a.x(), a.y(), -h}, {b.x(), b.y(), -h}, {b.x(), b.y(), h}, {a.x(), a.y(), h}});
    mesh.uvs.insert(mesh.uvs.end(), {{u0, 1.0f}, {u1, 1.0f}, {u1, 0.0f}, {u0, 0.0f}});
    mesh.triangles.insert(mesh.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  for (const float z : {-h, h}) {  // caps: a fan around the centre
    const uint32_t centre = static_cast<uint32_t>(mesh.positions_o.size());
    mesh.positions_o.emplace_back(0.0f, 0.0f, z);
    mesh.uvs.emplace_back(0.5f, 0.5f);
    for (int k = 0; k < sides; ++k) {
      const Eigen::Vector2f a = corner(k);
      mesh.positions_o.emplace_back(a.x(), a.y(), z);
      mesh.uvs.emplace_back(0.5f + 0.25f * a.x() / r, 0.5f + 0.25f * a.y() / r);
    }
    for (int k = 0; k < sides; ++k) {  // counter-clockwise seen from outside
      const uint32_t here = centre + 1 + static_cast<uint32_t>(k);
      const uint32_t next = centre + 1 + static_cast<uint32_t>((k + 1) % sides);
      if (z > 0) mesh.triangles.insert(mesh.triangles.end(), {centre, here, next});
      else mesh.triangles.insert(mesh.triangles.end(), {centre, next, here});
    }
  }
  return mesh;
}

namespace {

enum class DrawableKind { kMesh, kPoints, kLines, kSplats };

struct Drawable {
  DrawableKind kind;
  GLuint list = 0;  // display list; unused (0) for splats
  int texture = -1;
  float size_px = 1.0f;
  int splats = -1;  // index into Impl::splat_sets for kSplats
};

// Splats are expanded in chunks of this many hexagons (7 vertices, 6 triangles each).
constexpr int kSplatChunk = 16384;
constexpr int kSplatSides = 6;

// Equal-area hexagon: (3 sqrt 3 / 2) R^2 = pi r^2.
const float kHexagonRadiusScale =
    static_cast<float>(std::sqrt(2.0 * M_PI / (3.0 * std::sqrt(3.0))));

// Below this projected radius a splat is drawn as a square of the disc's area (4 vertices, 2
// triangles) instead of a hexagon (7 and 6): a third of the cost, and no visible difference.
constexpr float kQuadBelowRadiusPx = 2.0f;
const float kSquareHalfSideScale = static_cast<float>(0.5 * std::sqrt(M_PI));

// Draws one splat set seen from the camera at T_c_o (object frame o into the camera frame);
// `fx_px` converts a radius at unit depth into pixels.
void drawSplats(const SplatSet& set, const SE3& T_c_o, double near_m, double fx_px,
                std::vector<float>* vertices, std::vector<uint8_t>* colours,
                std::vector<float>* quad_vertices, std::vector<uint8_t>* quad_colours,
                const std::vector<GLuint>& indices) {
  const Eigen::Matrix3f R_c_o = T_c_o.rotationMatrix().cast<float>();
  const Eigen::Vector3f t_c_o = T_c_o.translation().cast<float>();
  const Eigen::Vector3f eye_o = -(R_c_o.transpose() * t_c_o);
  const Eigen::Vector3f axis_o = R_c_o.row(2).transpose();  // optical axis in the object frame
  const float near = static_cast<float>(near_m);
  float cos_k[kSplatSides], sin_k[kSplatSides];
  for (int k = 0; k < kSplatSides; ++k) {
    cos_k[k] = std::cos(2.0f * static_cast<float>(M_PI) * k / kSplatSides);
    sin_k[k] = std::sin(2.0f * static_cast<float>(M_PI) * k / kSplatSides);
  }
  vertices->resize(static_cast<std::size_t>(kSplatChunk) * (kSplatSides + 1) * 3);
  colours->resize(static_cast<std::size_t>(kSplatChunk) * (kSplatSides + 1) * 4);
  quad_vertices->resize(static_cast<std::size_t>(kSplatChunk) * 4 * 3);
  quad_colours->resize(static_cast<std::size_t>(kSplatChunk) * 4 * 4);
  const float fx = static_cast<float>(fx_px);
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_COLOR_ARRAY);
  int in_chunk = 0, quads_in_chunk = 0;
  auto flush = [&] {
    if (in_chunk == 0) return;
    glVertexPointer(3, GL_FLOAT, 0, vertices->data());
    glColorPointer(4, GL_UNSIGNED_BYTE, 0, colours->data());
    glDrawElements(GL_TRIANGLES, 3 * kSplatSides * in_chunk, GL_UNSIGNED_INT, indices.data());
    in_chunk = 0;
  };
  auto flush_quads = [&] {
    if (quads_in_chunk == 0) return;
    glVertexPointer(3, GL_FLOAT, 0, quad_vertices->data());
    glColorPointer(4, GL_UNSIGNED_BYTE, 0, quad_colours->data());
    glDrawArrays(GL_QUADS, 0, 4 * quads_in_chunk);
    quads_in_chunk = 0;
  };
  for (std::size_t i = 0; i < set.positions_o.size(); ++i) {
    const Eigen::Vector3f& p = set.positions_o[i];
    const Eigen::Vector3f ray = p - eye_o;
    const float depth = ray.dot(axis_o);
    if (depth + set.radii_m[i] < near) continue;  // wholly behind the near plane
    const Eigen::Vector3f& n = set.normals_o[i];
    const float n_dot_ray = n.dot(ray);
    if (set.cull_back_facing && n_dot_ray > 0.0f) continue;
    const float shade =
        set.ambient + (1.0f - set.ambient) * std::min(1.0f, std::abs(n_dot_ray) / ray.norm());
    const Eigen::Vector3f helper =
        std::abs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
    const Eigen::Vector3f axis = n.cross(helper).normalized();
    const Eigen::Vector3f c = set.colours_rgb[i] * (255.0f * shade);
    const uint8_t rgba[4] = {static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, c.x()))),
                             static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, c.y()))),
                             static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, c.z()))), 255};
    if (depth > near && fx * set.radii_m[i] < kQuadBelowRadiusPx * depth) {
      const Eigen::Vector3f e1 = axis * (kSquareHalfSideScale * set.radii_m[i]);
      const Eigen::Vector3f e2 = n.cross(e1);
      float* v = quad_vertices->data() + static_cast<std::size_t>(quads_in_chunk) * 4 * 3;
      uint8_t* col = quad_colours->data() + static_cast<std::size_t>(quads_in_chunk) * 4 * 4;
      const Eigen::Vector3f corners[4] = {p - e1 - e2, p + e1 - e2, p + e1 + e2, p - e1 + e2};
      for (int k = 0; k < 4; ++k) {
        v[3 * k] = corners[k].x();
        v[3 * k + 1] = corners[k].y();
        v[3 * k + 2] = corners[k].z();
        std::copy(rgba, rgba + 4, col + 4 * k);
      }
      if (++quads_in_chunk == kSplatChunk) flush_quads();
      continue;
    }
    const Eigen::Vector3f e1 = axis * (kHexagonRadiusScale * set.radii_m[i]);
    const Eigen::Vector3f e2 = n.cross(e1);
    float* v = vertices->data() + static_cast<std::size_t>(in_chunk) * (kSplatSides + 1) * 3;
    uint8_t* col = colours->data() + static_cast<std::size_t>(in_chunk) * (kSplatSides + 1) * 4;
    for (int k = 0; k <= kSplatSides; ++k) {
      const Eigen::Vector3f q =
          k == 0 ? p : Eigen::Vector3f(p + cos_k[k - 1] * e1 + sin_k[k - 1] * e2);
      v[3 * k] = q.x();
      v[3 * k + 1] = q.y();
      v[3 * k + 2] = q.z();
      std::copy(rgba, rgba + 4, col + 4 * k);
    }
    if (++in_chunk == kSplatChunk) flush();
  }
  flush();
  flush_quads();
  glDisableClientState(GL_COLOR_ARRAY);
  glDisableClientState(GL_VERTEX_ARRAY);
}

// Colour = texture (unit 0, white when untextured) x vertex colour x constant (unit 1: gain in
// RGB, item label in alpha). Unit 1 always samples the 1x1 white texture.
void setUpTextureUnits(GLuint white_texture) {
  glActiveTexture(GL_TEXTURE1);
  glEnable(GL_TEXTURE_2D);
  glBindTexture(GL_TEXTURE_2D, white_texture);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_COMBINE);
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_MODULATE);
  glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE0_RGB, GL_PREVIOUS);
  glTexEnvi(GL_TEXTURE_ENV, GL_OPERAND0_RGB, GL_SRC_COLOR);
  glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE1_RGB, GL_CONSTANT);
  glTexEnvi(GL_TEXTURE_ENV, GL_OPERAND1_RGB, GL_SRC_COLOR);
  glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_ALPHA, GL_REPLACE);
  glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE0_ALPHA, GL_CONSTANT);
  glTexEnvi(GL_TEXTURE_ENV, GL_OPERAND0_ALPHA, GL_SRC_ALPHA);
  glActiveTexture(GL_TEXTURE0);
  glEnable(GL_TEXTURE_2D);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);  // texture x vertex colour
}

void setItemColour(GLuint texture, float gain, uint8_t label) {
  glBindTexture(GL_TEXTURE_2D, texture);  // unit 0 is active
  const GLfloat constant[4] = {gain, gain, gain, label / 255.0f};
  glActiveTexture(GL_TEXTURE1);
  glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, constant);
  glActiveTexture(GL_TEXTURE0);
}

}  // namespace

struct OffscreenRenderer::Impl {
  int width = 0, height = 0;
  OSMesaContext context = nullptr;
  std::vector<uint8_t> colour_bgra;  // OSMesa draws here (GL row order: row 0 = image row 0)
  std::vector<GLuint> textures;
  GLuint white_texture = 0;
  std::vector<Drawable> drawables;
  std::vector<SplatSet> splat_sets;
  std::vector<float> splat_vertices;  // chunk buffers reused by every splat draw
  std::vector<uint8_t> splat_colours;
  std::vector<float> quad_vertices;
  std::vector<uint8_t> quad_colours;
  std::vector<GLuint> splat_indices;  // the fan pattern of one chunk

  void makeCurrent() {
    if (!OSMesaMakeCurrent(context, colour_bgra.data(), GL_UNSIGNED_BYTE, width, height)) {
      throw std::runtime_error("OSMesaMakeCurrent failed");
    }
  }
};

OffscreenRenderer::OffscreenRenderer(int width, int height) : impl_(std::make_unique<Impl>()) {
  LTLO_ASSERT(width > 0 && height > 0, "renderer size " << width << "x" << height);
  impl_->width = width;
  impl_->height = height;
  impl_->colour_bgra.assign(static_cast<size_t>(width) * height * 4, 0);
  impl_->context = OSMesaCreateContextExt(OSMESA_BGRA, 24, 0, 0, nullptr);
  if (impl_->context == nullptr) throw std::runtime_error("OSMesaCreateContextExt failed");
  impl_->makeCurrent();
  OSMesaPixelStore(OSMESA_Y_UP, 1);  // buffer row 0 = GL window row 0 = image row 0 (see header)

  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_LIGHTING);
  glDisable(GL_BLEND);
  glDisable(GL_DITHER);
  glDisable(GL_MULTISAMPLE);
  glEnable(GL_TEXTURE_2D);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glHint(GL_PERSPECTIVE_CORRECTION_HINT, GL_NICEST);

  const uint8_t white[3] = {255, 255, 255};
  glGenTextures(1, &impl_->white_texture);
  glBindTexture(GL_TEXTURE_2D, impl_->white_texture);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, 1, 1, 0, GL_RGB, GL_UNSIGNED_BYTE, white);
  setUpTextureUnits(impl_->white_texture);
}

OffscreenRenderer::~OffscreenRenderer() {
  if (impl_ && impl_->context) {
    impl_->makeCurrent();
    for (const Drawable& d : impl_->drawables) {
      if (d.list != 0) glDeleteLists(d.list, 1);
    }
    glDeleteTextures(static_cast<GLsizei>(impl_->textures.size()), impl_->textures.data());
    glDeleteTextures(1, &impl_->white_texture);
    OSMesaDestroyContext(impl_->context);
  }
}

void OffscreenRenderer::clearDrawables() {
  impl_->makeCurrent();
  for (const Drawable& d : impl_->drawables) {
    if (d.list != 0) glDeleteLists(d.list, 1);
  }
  impl_->drawables.clear();
  impl_->splat_sets.clear();
}

int OffscreenRenderer::width() const { return impl_->width; }
int OffscreenRenderer::height() const { return impl_->height; }

int OffscreenRenderer::addTexture(const cv::Mat& bgr) {
  LTLO_ASSERT(bgr.type() == CV_8UC3 && !bgr.empty(), "addTexture expects a CV_8UC3 image");
  impl_->makeCurrent();
  const cv::Mat contiguous = bgr.isContinuous() ? bgr : bgr.clone();
  GLuint id = 0;
  glGenTextures(1, &id);
  glBindTexture(GL_TEXTURE_2D, id);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_GENERATE_MIPMAP, GL_TRUE);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, contiguous.cols, contiguous.rows, 0, GL_BGR,
               GL_UNSIGNED_BYTE, contiguous.data);
  impl_->textures.push_back(id);
  return static_cast<int>(impl_->textures.size()) - 1;
}

int OffscreenRenderer::addMesh(const Mesh& mesh) {
  const bool textured = mesh.texture >= 0;
  LTLO_ASSERT(mesh.texture < static_cast<int>(impl_->textures.size()),
              "unknown texture " << mesh.texture);
  LTLO_ASSERT(!textured || mesh.uvs.size() == mesh.positions_o.size(), "mesh uvs size");
  LTLO_ASSERT(mesh.colours_rgb.empty() || mesh.colours_rgb.size() == mesh.positions_o.size(),
              "mesh colours size");
  LTLO_ASSERT(mesh.triangles.size() % 3 == 0, "mesh triangles not a multiple of 3");
  impl_->makeCurrent();
  Drawable d{DrawableKind::kMesh, glGenLists(1), mesh.texture, 1.0f};
  glNewList(d.list, GL_COMPILE);
  glBegin(GL_TRIANGLES);
  glColor3f(1.0f, 1.0f, 1.0f);
  for (uint32_t index : mesh.triangles) {
    LTLO_ASSERT(index < mesh.positions_o.size(), "mesh index " << index << " out of range");
    if (textured) glTexCoord2fv(mesh.uvs[index].data());
    if (!mesh.colours_rgb.empty()) glColor3fv(mesh.colours_rgb[index].data());
    glVertex3fv(mesh.positions_o[index].data());
  }
  glEnd();
  glEndList();
  impl_->drawables.push_back(d);
  return static_cast<int>(impl_->drawables.size()) - 1;
}

int OffscreenRenderer::addPoints(const PointSet& points) {
  LTLO_ASSERT(points.colours_rgb.empty() || points.colours_rgb.size() == points.positions_o.size(),
              "point colours size");
  impl_->makeCurrent();
  Drawable d{DrawableKind::kPoints, glGenLists(1), -1, points.size_px};
  glNewList(d.list, GL_COMPILE);
  glBegin(GL_POINTS);
  glColor3f(1.0f, 1.0f, 1.0f);
  for (size_t i = 0; i < points.positions_o.size(); ++i) {
    if (!points.colours_rgb.empty()) glColor3fv(points.colours_rgb[i].data());
    glVertex3fv(points.positions_o[i].data());
  }
  glEnd();
  glEndList();
  impl_->drawables.push_back(d);
  return static_cast<int>(impl_->drawables.size()) - 1;
}

int OffscreenRenderer::addLines(const LineSet& lines) {
  LTLO_ASSERT(lines.positions_o.size() % 2 == 0, "line vertices not a multiple of 2");
  LTLO_ASSERT(lines.colours_rgb.empty() || lines.colours_rgb.size() == lines.positions_o.size(),
              "line colours size");
  impl_->makeCurrent();
  Drawable d{DrawableKind::kLines, glGenLists(1), -1, lines.width_px};
  glNewList(d.list, GL_COMPILE);
  glBegin(GL_LINES);
  glColor3f(1.0f, 1.0f, 1.0f);
  for (size_t i = 0; i < lines.positions_o.size(); ++i) {
    if (!lines.colours_rgb.empty()) glColor3fv(lines.colours_rgb[i].data());
    glVertex3fv(lines.positions_o[i].data());
  }
  glEnd();
  glEndList();
  impl_->drawables.push_back(d);
  return static_cast<int>(impl_->drawables.size()) - 1;
}

int OffscreenRenderer::addSplats(SplatSet splats) {
  const std::size_t n = splats.positions_o.size();
  LTLO_ASSERT(
      splats.normals_o.size() == n && splats.radii_m.size() == n && splats.colours_rgb.size() == n,
      "addSplats: sizes differ");
  LTLO_ASSERT(splats.ambient >= 0.0f && splats.ambient <= 1.0f, "ambient " << splats.ambient);
  Impl& im = *impl_;
  if (im.splat_indices.empty()) {
    for (int s = 0; s < kSplatChunk; ++s) {
      const GLuint centre = static_cast<GLuint>(s * (kSplatSides + 1));
      for (int k = 0; k < kSplatSides; ++k) {
        im.splat_indices.insert(im.splat_indices.end(),
                                {centre, centre + 1 + k, centre + 1 + (k + 1) % kSplatSides});
      }
    }
  }
  im.splat_sets.push_back(std::move(splats));
  Drawable d{DrawableKind::kSplats, 0, -1, 1.0f, static_cast<int>(im.splat_sets.size()) - 1};
  im.drawables.push_back(d);
  return static_cast<int>(im.drawables.size()) - 1;
}

Eigen::Matrix4d OffscreenRenderer::projectionMatrix(const PinholeCamera& camera, double near_m,
                                                    double far_m) {
  // Pixel u spans window x in [u, u + 1]; x_ndc = 2 * (u + 0.5) / W - 1 with u = fx X / Z + cx,
  // so x_clip = (2 fx / W) X + ((2 cx + 1) / W - 1) Z with w_clip = Z; likewise y with GL row v
  // = image row v. Depth: z_ndc = a + b / Z maps [near, far] to [-1, 1].
  const double W = camera.width();
  const double H = camera.height();
  const double a = (far_m + near_m) / (far_m - near_m);
  const double b = -2.0 * far_m * near_m / (far_m - near_m);
  Eigen::Matrix4d P = Eigen::Matrix4d::Zero();
  P(0, 0) = 2.0 * camera.fx() / W;
  P(0, 2) = (2.0 * camera.cx() + 1.0) / W - 1.0;
  P(1, 1) = 2.0 * camera.fy() / H;
  P(1, 2) = (2.0 * camera.cy() + 1.0) / H - 1.0;
  P(2, 2) = a;
  P(2, 3) = b;
  P(3, 2) = 1.0;
  return P;
}

RenderResult OffscreenRenderer::render(const RenderView& view, const std::vector<DrawItem>& items) {
  Impl& im = *impl_;
  LTLO_ASSERT(view.camera.width() == im.width && view.camera.height() == im.height,
              "camera " << view.camera.width() << "x" << view.camera.height() << " vs renderer "
                        << im.width << "x" << im.height);
  LTLO_ASSERT(view.near_m > 0 && view.far_m > view.near_m, "clip planes");
  im.makeCurrent();
  glViewport(0, 0, im.width, im.height);
  glClearColor(view.background_rgb.x(), view.background_rgb.y(), view.background_rgb.z(), 0.0f);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

  const Eigen::Matrix4d P = projectionMatrix(view.camera, view.near_m, view.far_m);
  glMatrixMode(GL_PROJECTION);
  glLoadMatrixd(P.data());  // Eigen is column-major like OpenGL
  glMatrixMode(GL_MODELVIEW);
  for (const DrawItem& item : items) {
    LTLO_ASSERT(item.drawable >= 0 && item.drawable < static_cast<int>(im.drawables.size()),
                "unknown drawable " << item.drawable);
    const Drawable& d = im.drawables[item.drawable];
    const SE3 T_c_o = view.T_c_w * item.T_w_o;
    const Eigen::Matrix4d T_c_o_matrix = T_c_o.matrix();
    glLoadMatrixd(T_c_o_matrix.data());
    const bool textured = d.texture >= 0;
    setItemColour(textured ? im.textures[d.texture] : im.white_texture, item.gain, item.label);
    if (d.kind == DrawableKind::kPoints) glPointSize(d.size_px);
    if (d.kind == DrawableKind::kLines) glLineWidth(d.size_px);
    if (d.kind == DrawableKind::kSplats) {
      drawSplats(im.splat_sets[d.splats], T_c_o, view.near_m, view.camera.fx(),
                 &im.splat_vertices, &im.splat_colours, &im.quad_vertices, &im.quad_colours,
                 im.splat_indices);
    } else {
      glCallList(d.list);
    }
  }
  glFinish();

  RenderResult result;
  const cv::Mat bgra(im.height, im.width, CV_8UC4, im.colour_bgra.data());
  result.bgr.create(im.height, im.width, CV_8UC3);
  result.labels.create(im.height, im.width, CV_8U);
  cv::Mat outputs[] = {result.bgr, result.labels};
  const int from_to[] = {0, 0, 1, 1, 2, 2, 3, 3};
  cv::mixChannels(&bgra, 1, outputs, 2, from_to, 4);

  cv::Mat window_depth(im.height, im.width, CV_32F);
  glReadPixels(0, 0, im.width, im.height, GL_DEPTH_COMPONENT, GL_FLOAT, window_depth.data);
  // Window depth d in [0, 1] -> z_ndc = 2 d - 1 = a + b / Z -> Z = b / (z_ndc - a).
  const double a = (view.far_m + view.near_m) / (view.far_m - view.near_m);
  const double b = -2.0 * view.far_m * view.near_m / (view.far_m - view.near_m);
  result.depth_m.create(im.height, im.width, CV_32F);
  for (int v = 0; v < im.height; ++v) {
    const float* src = window_depth.ptr<float>(v);
    float* dst = result.depth_m.ptr<float>(v);
    for (int u = 0; u < im.width; ++u) {
      const double d = src[u];
      dst[u] = d >= 1.0 ? 0.0f : static_cast<float>(b / (2.0 * d - 1.0 - a));
    }
  }
  const GLenum error = glGetError();
  if (error != GL_NO_ERROR) {
    throw std::runtime_error("OpenGL error " + std::to_string(error) + " while rendering");
  }
  return result;
}

}  // namespace ltlo::render
