#include "mcslam/synth/renderer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "mcslam/core/error.hpp"
#include "mcslam/core/parallel.hpp"
#include "random.hpp"

namespace mcslam::synth {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Tolerance (metres) on rectangle extents, so that rays through room edges never slip through.
constexpr double kEdgeTolerance = 1e-6;
constexpr double kMinDistance = 1e-9;

/// Per-frame description of a room rectangle in the camera frame.
struct QuadView {
  Eigen::Vector3d o, u, v, n;
  double size_u = 0.0, size_v = 0.0;
  double n_dot_o = 0.0;
  const std::vector<cv::Mat>* mips = nullptr;
  double texel = 0.0;
  float shade = 1.0f;
};

/// Per-frame description of an object box in the camera frame.
struct BoxView {
  Eigen::Matrix3d R_o_c;
  Eigen::Matrix3d R_c_o;
  Eigen::Vector3d o;  // camera centre in the object frame
  Eigen::Vector3d h;
  double u_min = -kInf, u_max = kInf, v_min = -kInf, v_max = kInf;  // image bounds (culling)
  const Texture* texture = nullptr;
  std::array<float, 6> shade{};
  int object = -1;  // index into Scene::objects
};

struct Hit {
  double depth = kInf;
  int prim = -1;  // 0..Q-1 room quads, Q + 6 * box + face for boxes
  int box = -1;   // index into FrameSetup::boxes
  int face = 0;
  Eigen::Vector3d p_o;  // hit in the box frame (boxes only)
};

struct FrameSetup {
  std::vector<QuadView> quads;
  std::vector<BoxView> boxes;
  double fx = 1, fy = 1, cx = 0, cy = 0;
};

inline void bilinear(const cv::Mat& img, double x, double y, float out[3]) {
  const int w = img.cols, h = img.rows;
  x = std::clamp(x, 0.0, w - 1.0);
  y = std::clamp(y, 0.0, h - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  const cv::Vec3b* r0 = img.ptr<cv::Vec3b>(y0);
  const cv::Vec3b* r1 = img.ptr<cv::Vec3b>(y1);
  for (int c = 0; c < 3; ++c) {
    const float top = r0[x0][c] + ax * (r0[x1][c] - r0[x0][c]);
    const float bottom = r1[x0][c] + ax * (r1[x1][c] - r1[x0][c]);
    out[c] = top + ay * (bottom - top);
  }
}

/// Trilinear sample at texture coordinates (s, t) metres, footprint in level-0 texels.
inline void sample(const std::vector<cv::Mat>& mips, double texel, double s, double t,
                   double footprint, float out[3]) {
  const double level = footprint > 1.0 ? std::log2(footprint) : 0.0;
  const int last = static_cast<int>(mips.size()) - 1;
  const int l0 = std::min(static_cast<int>(level), last);
  auto at_level = [&](int l, float o[3]) {
    const double scale = 1.0 / (texel * static_cast<double>(1 << l));
    bilinear(mips[l], s * scale - 0.5, t * scale - 0.5, o);
  };
  at_level(l0, out);
  const float frac = static_cast<float>(level - l0);
  if (l0 < last && frac > 0.0f) {
    float next[3];
    at_level(l0 + 1, next);
    for (int c = 0; c < 3; ++c) out[c] += frac * (next[c] - out[c]);
  }
}

/// Nearest intersection of the camera-frame ray X = lambda * d (d.z = 1) at pixel (u, v).
inline Hit cast(const FrameSetup& f, const Eigen::Vector3d& d, double u, double v) {
  Hit hit;
  const int nq = static_cast<int>(f.quads.size());
  for (int q = 0; q < nq; ++q) {
    const QuadView& quad = f.quads[q];
    const double nd = quad.n.dot(d);
    if (nd >= -1e-12) continue;  // back-facing or parallel
    const double lambda = quad.n_dot_o / nd;
    if (lambda <= kMinDistance || lambda >= hit.depth) continue;
    const Eigen::Vector3d r = lambda * d - quad.o;
    const double s = quad.u.dot(r), t = quad.v.dot(r);
    if (s < -kEdgeTolerance || s > quad.size_u + kEdgeTolerance || t < -kEdgeTolerance ||
        t > quad.size_v + kEdgeTolerance)
      continue;
    hit.depth = lambda;
    hit.prim = q;
  }
  const int nb = static_cast<int>(f.boxes.size());
  for (int b = 0; b < nb; ++b) {
    const BoxView& box = f.boxes[b];
    if (u < box.u_min || u > box.u_max || v < box.v_min || v > box.v_max) continue;
    const Eigen::Vector3d dd = box.R_o_c * d;
    double t_near = -kInf, t_far = kInf;
    int axis = -1;
    bool miss = false;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(dd[k]) < 1e-15) {
        if (std::abs(box.o[k]) > box.h[k]) miss = true;
        continue;
      }
      const double inv = 1.0 / dd[k];
      double t1 = (-box.h[k] - box.o[k]) * inv, t2 = (box.h[k] - box.o[k]) * inv;
      if (t1 > t2) std::swap(t1, t2);
      if (t1 > t_near) t_near = t1, axis = k;
      t_far = std::min(t_far, t2);
    }
    if (miss || axis < 0 || t_near > t_far || t_near <= kMinDistance || t_near >= hit.depth)
      continue;
    hit.depth = t_near;
    hit.box = b;
    hit.face = 2 * axis + (dd[axis] < 0.0 ? 1 : 0);
    hit.prim = nq + 6 * b + hit.face;
    hit.p_o = box.o + t_near * dd;
    hit.p_o[axis] = dd[axis] < 0.0 ? box.h[axis] : -box.h[axis];
  }
  return hit;
}

/// Shaded colour of a hit; footprint_scale scales the pixel footprint (1 for a whole pixel).
inline void shade_hit(const FrameSetup& f, const Hit& hit, const Eigen::Vector3d& d,
                      double footprint_scale, float out[3]) {
  if (hit.prim < 0) {
    out[0] = out[1] = out[2] = 0.0f;
    return;
  }
  Eigen::Vector3d n, a, b;
  double s, t, texel;
  const std::vector<cv::Mat>* mips;
  float shade;
  const Eigen::Vector3d x = hit.depth * d;
  if (hit.box < 0) {
    const QuadView& q = f.quads[hit.prim];
    n = q.n, a = q.u, b = q.v;
    s = q.u.dot(x - q.o);
    t = q.v.dot(x - q.o);
    mips = q.mips;
    texel = q.texel;
    shade = q.shade;
  } else {
    const BoxView& box = f.boxes[hit.box];
    const int axis = hit.face / 2, i = (axis + 1) % 3, j = (axis + 2) % 3;
    n = box.R_c_o.col(axis) * ((hit.face & 1) ? 1.0 : -1.0);
    a = box.R_c_o.col(i);
    b = box.R_c_o.col(j);
    s = hit.p_o[i] + box.h[i];
    t = hit.p_o[j] + box.h[j];
    mips = &box.texture->layers[hit.face];
    texel = box.texture->texel_size;
    shade = box.shade[hit.face];
  }
  // Ray differentials: derivative of the hit point with respect to the pixel coordinates.
  const double nd = n.dot(d);
  const Eigen::Vector3d eu(1.0 / f.fx, 0.0, 0.0), ev(0.0, 1.0 / f.fy, 0.0);
  const Eigen::Vector3d dxu = hit.depth * (eu - (n.dot(eu) / nd) * d);
  const Eigen::Vector3d dxv = hit.depth * (ev - (n.dot(ev) / nd) * d);
  const double au = a.dot(dxu), bu = b.dot(dxu), av = a.dot(dxv), bv = b.dot(dxv);
  const double len2 = std::max(au * au + bu * bu, av * av + bv * bv);
  const double footprint = footprint_scale * std::sqrt(len2) / texel;
  sample(*mips, texel, s, t, footprint, out);
  for (int c = 0; c < 3; ++c) out[c] *= shade;
}

/// The view from T_w_c at time t. Boxes entirely outside the image are dropped, unless
/// keep_all_boxes (rolling shutter: then boxes[b] is Scene::objects[b] in every row's setup, so
/// that primitive ids compare across rows); a kept box outside the image never passes culling.
FrameSetup setup_frame(const Scene& scene, const PinholeCamera& camera, const SE3& T_w_c, double t,
                       bool keep_all_boxes = false) {
  FrameSetup f;
  f.fx = camera.fx, f.fy = camera.fy, f.cx = camera.cx, f.cy = camera.cy;
  const SE3 T_c_w = T_w_c.inverse();
  const Eigen::Matrix3d R_c_w = T_c_w.rotation();
  auto lambert = [&](const Eigen::Vector3d& n_w) {
    return static_cast<float>(scene.ambient +
                              scene.diffuse * std::max(0.0, n_w.dot(scene.light_direction)));
  };
  for (const Surface& s : scene.surfaces) {
    QuadView q;
    q.o = T_c_w * s.origin;
    q.u = R_c_w * s.u_axis;
    q.v = R_c_w * s.v_axis;
    q.n = R_c_w * s.normal();
    q.size_u = s.size_u;
    q.size_v = s.size_v;
    q.n_dot_o = q.n.dot(q.o);
    const Texture& texture = *scene.textures.at(s.texture_id);
    q.mips = &texture.layers.at(0);
    q.texel = texture.texel_size;
    q.shade = lambert(s.normal());
    f.quads.push_back(q);
  }
  for (std::size_t index = 0; index < scene.objects.size(); ++index) {
    const SceneObject& object = scene.objects[index];
    const SE3 T_w_o = object.pose_at(t);
    const SE3 T_o_c = T_w_o.inverse() * T_w_c;
    BoxView b;
    b.R_o_c = T_o_c.rotation();
    b.R_c_o = b.R_o_c.transpose();
    b.o = T_o_c.translation();
    b.h = object.half_extents;
    b.texture = scene.textures.at(object.texture_id).get();
    b.object = static_cast<int>(index);
    const Eigen::Matrix3d R_w_o = T_w_o.rotation();
    for (int face = 0; face < 6; ++face)
      b.shade[face] = lambert(R_w_o.col(face / 2) * ((face & 1) ? 1.0 : -1.0));
    // Image-space bounds when the whole box is in front of the camera.
    bool in_front = true;
    double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
    for (const Eigen::Vector3d& corner_w : object.corners_at(t)) {
      const Eigen::Vector3d p = T_c_w * corner_w;
      if (p.z() < 1e-3) {
        in_front = false;
        break;
      }
      const Eigen::Vector2d uv = camera.project(p);
      u0 = std::min(u0, uv.x()), u1 = std::max(u1, uv.x());
      v0 = std::min(v0, uv.y()), v1 = std::max(v1, uv.y());
    }
    if (in_front) {
      b.u_min = u0 - 1.0, b.u_max = u1 + 1.0, b.v_min = v0 - 1.0, b.v_max = v1 + 1.0;
      if (b.u_max < -1.0 || b.v_max < -1.0 || b.u_min > camera.width || b.v_min > camera.height) {
        if (!keep_all_boxes) continue;  // entirely outside the image
        b.u_min = b.v_min = kInf;
      }
    }
    f.boxes.push_back(b);
  }
  return f;
}

}  // namespace

double kinect_depth_sigma(double z) { return 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4); }

cv::Mat apply_kinect_depth_noise(const cv::Mat& depth, std::uint64_t seed) {
  CV_Assert(depth.type() == CV_32FC1);
  constexpr float kMinRange = 0.4f, kMaxRange = 4.5f, kJump = 0.1f;
  constexpr double kFactor = 5000.0;
  cv::Mat out(depth.size(), CV_32FC1);
  const int w = depth.cols, h = depth.rows;
  parallel_for(0, h, [&](int first, int last) {
    for (int y = first; y < last; ++y) {
      const float* row = depth.ptr<float>(y);
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        const float z = row[x];
        bool valid = z >= kMinRange && z <= kMaxRange;
        if (valid) {
          const float neighbours[4] = {x > 0 ? row[x - 1] : z, x + 1 < w ? row[x + 1] : z,
                                       y > 0 ? depth.ptr<float>(y - 1)[x] : z,
                                       y + 1 < h ? depth.ptr<float>(y + 1)[x] : z};
          for (float zn : neighbours)
            if (std::abs(zn - z) > kJump) valid = false;
        }
        if (!valid) {
          dst[x] = 0.0f;
          continue;
        }
        detail::Rng rng(detail::hash_combine(seed, static_cast<std::uint64_t>(y) * w + x));
        const double noisy = z + kinect_depth_sigma(z) * rng.normal();
        dst[x] = static_cast<float>(std::round(noisy * kFactor) / kFactor);
      }
    }
  });
  return out;
}

Renderer::Renderer(const Scene& scene, const PinholeCamera& camera, const RenderOptions& options)
    : scene_(scene), camera_(camera), options_(options) {}

namespace {

/// Whether pixel (x, y) borders a pixel of another primitive (a geometric edge).
bool on_edge(const cv::Mat& prim, int x, int y) {
  const int p = prim.ptr<int>(y)[x];
  for (int yy = std::max(0, y - 1); yy <= std::min(prim.rows - 1, y + 1); ++yy) {
    const int* r = prim.ptr<int>(yy);
    for (int xx = std::max(0, x - 1); xx <= std::min(prim.cols - 1, x + 1); ++xx)
      if (r[xx] != p) return true;
  }
  return false;
}

/// Pass 1: one ray through each pixel centre: depth, labels, the primitive hit and its colour.
template <class SetupOfRow>
void cast_pixel_centres(const PinholeCamera& camera, const SetupOfRow& setup_of,
                        RenderedFrame& frame, cv::Mat& prim, cv::Mat& colour) {
  const int w = camera.width, h = camera.height;
  parallel_for(0, h, [&](int first, int last) {
    for (int y = first; y < last; ++y) {
      const FrameSetup& f = setup_of(y);
      float* depth_row = frame.depth.ptr<float>(y);
      std::int16_t* label_row = frame.labels.ptr<std::int16_t>(y);
      int* prim_row = prim.ptr<int>(y);
      cv::Vec3f* colour_row = colour.ptr<cv::Vec3f>(y);
      for (int x = 0; x < w; ++x) {
        const Eigen::Vector3d d((x - f.cx) / f.fx, (y - f.cy) / f.fy, 1.0);
        const Hit hit = cast(f, d, x, y);
        depth_row[x] = hit.prim >= 0 ? static_cast<float>(hit.depth) : 0.0f;
        prim_row[x] = hit.prim;
        label_row[x] = static_cast<std::int16_t>(hit.box >= 0 ? f.boxes[hit.box].object : -1);
        shade_hit(f, hit, d, 1.0, colour_row[x].val);
      }
    }
  });
}

/// Pass 2: geometric edges anti-aliased with 4 rotated-grid subsamples, then the colour noise.
template <class SetupOfRow>
void shade_pixels(const PinholeCamera& camera, const RenderOptions& options,
                  std::uint64_t frame_seed, const SetupOfRow& setup_of, const cv::Mat& prim,
                  const cv::Mat& colour, cv::Mat& rgb) {
  const int w = camera.width, h = camera.height;
  const float sigma = static_cast<float>(options.rgb_noise_sigma);
  static constexpr double kSub[4][2] = {
      {-0.125, -0.375}, {0.375, -0.125}, {0.125, 0.375}, {-0.375, 0.125}};
  rgb.create(h, w, CV_8UC3);
  parallel_for(0, h, [&](int first, int last) {
    for (int y = first; y < last; ++y) {
      const FrameSetup& f = setup_of(y);
      const cv::Vec3f* colour_row = colour.ptr<cv::Vec3f>(y);
      cv::Vec3b* rgb_row = rgb.ptr<cv::Vec3b>(y);
      for (int x = 0; x < w; ++x) {
        float c[3] = {colour_row[x][0], colour_row[x][1], colour_row[x][2]};
        if (on_edge(prim, x, y)) {
          c[0] = c[1] = c[2] = 0.0f;
          for (const auto& o : kSub) {
            const double u = x + o[0], v = y + o[1];
            const Eigen::Vector3d d((u - f.cx) / f.fx, (v - f.cy) / f.fy, 1.0);
            float s[3];
            shade_hit(f, cast(f, d, u, v), d, 0.5, s);
            for (int k = 0; k < 3; ++k) c[k] += 0.25f * s[k];
          }
        }
        if (sigma > 0.0f) {
          const std::uint64_t hp =
              detail::hash_combine(frame_seed, static_cast<std::uint64_t>(y) * w + x);
          for (int k = 0; k < 3; ++k)
            c[k] += sigma * detail::approx_normal(detail::mix64(hp + static_cast<unsigned>(k)));
        }
        for (int k = 0; k < 3; ++k) rgb_row[x][k] = cv::saturate_cast<std::uint8_t>(c[k]);
      }
    }
  });
}

/// Renders the image with setup_of(y) (a const FrameSetup&) describing the view of row y, so that
/// a global-shutter render (one setup) pays nothing for the rolling-shutter option.
template <class SetupOfRow>
RenderedFrame render_rows(const PinholeCamera& camera, const RenderOptions& options, double t,
                          const SetupOfRow& setup_of) {
  const int w = camera.width, h = camera.height;
  RenderedFrame frame;
  frame.depth.create(h, w, CV_32FC1);
  frame.labels.create(h, w, CV_16SC1);
  cv::Mat prim(h, w, CV_32SC1);
  cv::Mat colour(h, w, CV_32FC3);
  cast_pixel_centres(camera, setup_of, frame, prim, colour);
  const std::uint64_t frame_seed = detail::hash_combine(options.noise_seed, detail::hash_double(t));
  shade_pixels(camera, options, frame_seed, setup_of, prim, colour, frame.rgb);
  if (options.depth_noise)
    frame.depth = apply_kinect_depth_noise(frame.depth, detail::hash_combine(frame_seed, 0xDE97));
  return frame;
}

}  // namespace

RenderedFrame Renderer::render(const SE3& T_w_c, double t) const {
  const FrameSetup f = setup_frame(scene_, camera_, T_w_c, t);
  return render_rows(camera_, options_, t, [&f](int) -> const FrameSetup& { return f; });
}

double Renderer::row_time(double t, int row, double readout_time) const {
  return t + (row + 0.5 - 0.5 * camera_.height) / camera_.height * readout_time;
}

RenderedFrame Renderer::render(const std::function<SE3(double)>& T_w_c_at, double t,
                               double readout_time) const {
  if (!std::isfinite(readout_time))
    throw InputError("Renderer::render: readout_time must be finite");
  if (readout_time == 0.0) return render(T_w_c_at(t), t);
  // One view per row (cheap next to the rays; serial, so T_w_c_at need not be thread-safe).
  std::vector<FrameSetup> setups;
  setups.reserve(static_cast<std::size_t>(camera_.height));
  for (int y = 0; y < camera_.height; ++y) {
    const double t_row = row_time(t, y, readout_time);
    setups.push_back(setup_frame(scene_, camera_, T_w_c_at(t_row), t_row, true));
  }
  return render_rows(camera_, options_, t, [&setups](int y) -> const FrameSetup& {
    return setups[static_cast<std::size_t>(y)];
  });
}

}  // namespace mcslam::synth
