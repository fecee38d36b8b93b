#include "mobmap/sim/corridor_scene.hpp"

#include "mobmap/gp/rule_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

namespace mobmap::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr double kNearPlane = 1e-3;  // metres; rays start at the optical centre

using perception::PinholeIntrinsics;

Eigen::Vector3d newellNormal(const std::vector<Eigen::Vector3d>& poly) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& p = poly[i];
    const Eigen::Vector3d& q = poly[(i + 1) % poly.size()];
    n += Eigen::Vector3d((p.y() - q.y()) * (p.z() + q.z()), (p.z() - q.z()) * (p.x() + q.x()),
                         (p.x() - q.x()) * (p.y() + q.y()));
  }
  return n.normalized();
}

// Clips a convex polygon to the half space z >= near (Sutherland-Hodgman).
std::vector<Eigen::Vector3d> clipNear(const std::vector<Eigen::Vector3d>& poly) {
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector3d& p = poly[i];
    const Eigen::Vector3d& q = poly[(i + 1) % poly.size()];
    const bool p_in = p.z() >= kNearPlane;
    const bool q_in = q.z() >= kNearPlane;
    if (p_in) out.push_back(p);
    if (p_in != q_in) {
      const double s = (kNearPlane - p.z()) / (q.z() - p.z());
      out.push_back(p + s * (q - p));
    }
  }
  return out;
}

// splitmix64: decorrelates (seed, frame) into a generator seed.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Uniform in [0,1) from the top 53 bits: defined by the standard, unlike
// std::uniform_real_distribution and std::normal_distribution, so noise is the same
// with every standard library.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

double gaussian(std::mt19937_64& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0,1]
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

std::array<std::uint8_t, 3> baseColour(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::kFloor: return {170, 160, 140};
    case SurfaceKind::kWall: return {200, 200, 210};
    case SurfaceKind::kRamp: return {90, 140, 200};
    case SurfaceKind::kRampSide: return {60, 90, 140};
    case SurfaceKind::kRough: return {150, 110, 70};
    case SurfaceKind::kBoxTop: return {220, 170, 60};
    case SurfaceKind::kBoxSide: return {180, 120, 40};
    case SurfaceKind::kStairTread: return {120, 180, 120};
    case SurfaceKind::kStairRiser: return {80, 130, 80};
    case SurfaceKind::kStairSide: return {70, 100, 70};
  }
  return {255, 0, 255};
}

std::vector<Eigen::Vector3d> boxFace(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int axis,
                                     bool upper) {
  // The rectangle of the box [lo, hi] at coordinate `axis` = lo or hi.
  const int a1 = (axis + 1) % 3;
  const int a2 = (axis + 2) % 3;
  Eigen::Vector3d c = lo;
  c[axis] = upper ? hi[axis] : lo[axis];
  std::vector<Eigen::Vector3d> poly(4, c);
  poly[1][a1] = hi[a1];
  poly[2][a1] = hi[a1];
  poly[2][a2] = hi[a2];
  poly[3][a2] = hi[a2];
  return poly;
}

}  // namespace

const char* toString(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::kFloor: return "floor";
    case SurfaceKind::kWall: return "wall";
    case SurfaceKind::kRamp: return "ramp";
    case SurfaceKind::kRampSide: return "ramp_side";
    case SurfaceKind::kRough: return "rough";
    case SurfaceKind::kBoxTop: return "box_top";
    case SurfaceKind::kBoxSide: return "box_side";
    case SurfaceKind::kStairTread: return "stair_tread";
    case SurfaceKind::kStairRiser: return "stair_riser";
    case SurfaceKind::kStairSide: return "stair_side";
  }
  return "unknown";
}

double PyramidField::heightAt(double x, double y) const {
  const double u = (x - x0) / pitch_m;
  const double v = (y - y0) / pitch_m;
  if (u < 0 || v < 0 || u > nx || v > ny) return 0.0;
  const double fu = u - std::floor(u);
  const double fv = v - std::floor(v);
  return height_m * (1.0 - 2.0 * std::max(std::abs(fu - 0.5), std::abs(fv - 0.5)));
}

std::vector<Triangle> PyramidField::triangles(int surface_id) const {
  std::vector<Triangle> tris;
  const double p = pitch_m;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      const double x = x0 + i * p, y = y0 + j * p;
      const Eigen::Vector3d c00(x, y, 0), c10(x + p, y, 0), c11(x + p, y + p, 0), c01(x, y + p, 0);
      const Eigen::Vector3d apex(x + 0.5 * p, y + 0.5 * p, height_m);
      tris.push_back({c00, c10, apex, surface_id});
      tris.push_back({c10, c11, apex, surface_id});
      tris.push_back({c11, c01, apex, surface_id});
      tris.push_back({c01, c00, apex, surface_id});
    }
  }
  return tris;
}

double PyramidField::exactAreaRatio() const {
  const double g = 2.0 * height_m / pitch_m;
  return std::sqrt(1.0 + g * g);
}

Eigen::Vector3d MovingObstacle::centreAt(int frame) const {
  if (frame <= start_frame) return from;
  if (frame >= end_frame) return to;
  const double s = static_cast<double>(frame - start_frame) / (end_frame - start_frame);
  return from + s * (to - from);
}

void validate(const CorridorParams& p) {
  auto fail = [](const char* field, double value, const char* rule) {
    std::ostringstream msg;
    msg << "CorridorParams: " << field << " is " << value << " (" << rule << ")";
    throw std::invalid_argument(msg.str());
  };
  if (p.frames < 1 || p.frames > 1000000) fail("frames", p.frames, "must be 1..1000000");
  if (!(p.frame_rate_hz > 0) || !std::isfinite(p.frame_rate_hz)) fail("frame_rate_hz", p.frame_rate_hz, "must be > 0");
  if (!(p.speed_mps >= 0) || !std::isfinite(p.speed_mps)) fail("speed_mps", p.speed_mps, "must be >= 0");
  if (!(p.camera_height_m > 0.1 && p.camera_height_m < 2.4)) fail("camera_height_m", p.camera_height_m, "must be in (0.1, 2.4)");
  // The camera's right axis does not depend on pitch: straight down (90) is a valid view.
  if (!(p.pitch_down_deg >= -90 && p.pitch_down_deg <= 90)) fail("pitch_down_deg", p.pitch_down_deg, "must be in [-90, 90]");
  if (!(p.kinect.axial_sigma_at_1m_m >= 0)) fail("kinect.axial_sigma_at_1m_m", p.kinect.axial_sigma_at_1m_m, "must be >= 0");
  if (!(p.kinect.baseline_m > 0)) fail("kinect.baseline_m", p.kinect.baseline_m, "must be > 0");
  if (!(p.kinect.disparity_subpixel >= 0)) fail("kinect.disparity_subpixel", p.kinect.disparity_subpixel, "must be >= 0");
  if (!(p.kinect.dropout_full_deg > p.kinect.dropout_start_deg)) fail("kinect.dropout_full_deg", p.kinect.dropout_full_deg, "must exceed dropout_start_deg");
  if (p.kinect.edge_window_px < 0 || p.kinect.edge_window_px > 31 || (p.kinect.edge_window_px > 0 && p.kinect.edge_window_px % 2 == 0)) {
    fail("kinect.edge_window_px", p.kinect.edge_window_px, "must be 0 or odd, at most 31");
  }
  if (!(p.kinect.flying_pixel_probability >= 0 && p.kinect.flying_pixel_probability <= 1)) {
    fail("kinect.flying_pixel_probability", p.kinect.flying_pixel_probability, "must be in [0, 1]");
  }
  if (!(p.kinect.edge_jump_px > 0) || !std::isfinite(p.kinect.edge_jump_px)) fail("kinect.edge_jump_px", p.kinect.edge_jump_px, "must be > 0");
  const RoughYardParams& y = p.yard;
  if (!(y.ridge_pitch_m >= 0.02 && y.ridge_pitch_m <= 0.4)) fail("yard.ridge_pitch_m", y.ridge_pitch_m, "must be in [0.02, 0.4]");
  if (!(y.ridge_height_m > 0 && y.ridge_height_m <= 0.3)) fail("yard.ridge_height_m", y.ridge_height_m, "must be in (0, 0.3]");
  if (!(y.block_pitch_m >= 0.02 && y.block_pitch_m <= 0.4)) fail("yard.block_pitch_m", y.block_pitch_m, "must be in [0.02, 0.4]");
  if (!(y.block_side_m > 0 && y.block_side_m < y.block_pitch_m)) fail("yard.block_side_m", y.block_side_m, "must be in (0, block_pitch_m)");
  if (!(y.block_height_m > 0 && y.block_height_m <= 0.3)) fail("yard.block_height_m", y.block_height_m, "must be in (0, 0.3]");
  if (!(y.stone_pitch_m >= 0.02 && y.stone_pitch_m <= 0.4)) fail("yard.stone_pitch_m", y.stone_pitch_m, "must be in [0.02, 0.4]");
  if (!(y.stone_min_side_m > 0 && y.stone_min_side_m <= y.stone_max_side_m && y.stone_max_side_m < y.stone_pitch_m)) {
    fail("yard.stone_max_side_m", y.stone_max_side_m, "must be at least stone_min_side_m (> 0) and under stone_pitch_m");
  }
  if (!(y.stone_min_height_m > 0 && y.stone_min_height_m <= y.stone_max_height_m && y.stone_max_height_m <= 0.3)) {
    fail("yard.stone_max_height_m", y.stone_max_height_m, "must be at least stone_min_height_m (> 0) and at most 0.3");
  }
  perception::validate(p.intrinsics);
}

int CorridorScene::addSurface(Surface s) {
  s.id = static_cast<int>(surfaces_.size()) + 1;
  if (s.kind != SurfaceKind::kRough) s.normal = newellNormal(s.polygons.front());
  s.slope_deg = std::acos(std::min(1.0, std::abs(s.normal.z()))) / kDeg;
  // Vertical faces: acos(0) is 90 up to rounding; make it exact.
  if (std::abs(s.normal.z()) < 1e-12) s.slope_deg = 90.0;
  if (std::abs(std::abs(s.normal.z()) - 1.0) < 1e-12) s.slope_deg = 0.0;
  s.expected_mobility = gp::RuleTable::paper().lookup(s.slope_deg, s.roughness);
  auto& target = s.moving ? moving_triangles_ : static_triangles_;
  if (s.kind != SurfaceKind::kRough) {
    for (const auto& poly : s.polygons) {
      for (std::size_t i = 1; i + 1 < poly.size(); ++i) {
        target.push_back({poly[0], poly[i], poly[i + 1], s.id});
      }
    }
  }
  surfaces_.push_back(std::move(s));
  return surfaces_.back().id;
}

void CorridorScene::buildRoughYard(double x_begin, double x_end, double half_width) {
  using V = Eigen::Vector3d;
  const RoughYardParams& y = params_.yard;
  struct Field {
    std::string name;
    double x0, x1, y0, y1;
  };
  // Beside the path (|y| >= 0.5), each field a whole number of its cells.
  const auto cells = [](double pitch, double length) { return std::max(1, static_cast<int>(std::floor(length / pitch + 1e-9))); };
  const double rp = y.ridge_pitch_m, bp = y.block_pitch_m, sp = y.stone_pitch_m;
  const std::vector<Field> fields = {
      {"pyramids", 1.4, 2.2, 0.5, 1.3},
      {"ridges along the path", 2.8, 3.8, 0.5, 0.5 + cells(rp, 0.8) * rp},
      {"ridges across the path", 2.8, 2.8 + cells(rp, 1.0) * rp, -1.3, -0.5},
      {"blocks", 4.4, 4.4 + cells(bp, 1.0) * bp, 0.5, 0.5 + cells(bp, 0.8) * bp},
      {"stones", 4.4, 4.4 + cells(sp, 1.0) * sp, -0.5 - cells(sp, 0.8) * sp, -0.5},
  };
  // The floor: the corridor's rectangle less the fields, in strips between their x edges.
  {
    std::vector<double> xs{x_begin, x_end};
    for (const Field& f : fields) xs.push_back(f.x0), xs.push_back(f.x1);
    std::sort(xs.begin(), xs.end());
    Surface floor;
    floor.name = "floor";
    floor.kind = SurfaceKind::kFloor;
    for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
      const double xa = xs[i], xb = xs[i + 1];
      if (xb - xa < 1e-9) continue;
      std::vector<std::pair<double, double>> holes;
      for (const Field& f : fields) {
        if (f.x0 < xb - 1e-9 && f.x1 > xa + 1e-9) holes.emplace_back(f.y0, f.y1);
      }
      std::sort(holes.begin(), holes.end());
      double ya = -half_width;
      holes.emplace_back(half_width, half_width);
      for (const auto& [h0, h1] : holes) {
        if (h0 > ya + 1e-9) floor.polygons.push_back({V(xa, ya, 0), V(xb, ya, 0), V(xb, h0, 0), V(xa, h0, 0)});
        ya = std::max(ya, h1);
      }
    }
    addSurface(std::move(floor));
  }
  // A field: its surface (footprint polygon, exact ratio) and its triangles.
  const auto addField = [&](const Field& f, const std::string& description, const std::vector<Triangle>& tris) {
    Surface s;
    s.name = f.name;
    s.kind = SurfaceKind::kRough;
    s.normal = V::UnitZ();
    s.description = description;
    s.polygons.push_back({V(f.x0, f.y0, 0), V(f.x1, f.y0, 0), V(f.x1, f.y1, 0), V(f.x0, f.y1, 0)});
    double area = 0;
    for (const Triangle& t : tris) {
      area += 0.5 * (t.b - t.a).cross(t.c - t.a).norm();
      s.top_m = std::max({s.top_m, t.a.z(), t.b.z(), t.c.z()});
    }
    s.roughness = area / ((f.x1 - f.x0) * (f.y1 - f.y0));
    const int id = addSurface(std::move(s));
    for (Triangle t : tris) {
      t.surface_id = id;
      static_triangles_.push_back(t);
    }
  };
  const auto quad = [](std::vector<Triangle>& tris, const V& a, const V& b, const V& c, const V& d) {
    tris.push_back({a, b, c, 0});
    tris.push_back({a, c, d, 0});
  };
  // A box standing on z = 0 over [xa, xb] x [ya, yb] inside the cell [cx0, cx1] x [cy0, cy1]:
  // its top, four sides and the cell's floor around it.
  const auto boxInCell = [&](std::vector<Triangle>& tris, double cx0, double cx1, double cy0, double cy1, double xa, double xb,
                             double ya, double yb, double h) {
    quad(tris, V(xa, ya, h), V(xb, ya, h), V(xb, yb, h), V(xa, yb, h));
    quad(tris, V(xa, ya, 0), V(xb, ya, 0), V(xb, ya, h), V(xa, ya, h));
    quad(tris, V(xb, ya, 0), V(xb, yb, 0), V(xb, yb, h), V(xb, ya, h));
    quad(tris, V(xb, yb, 0), V(xa, yb, 0), V(xa, yb, h), V(xb, yb, h));
    quad(tris, V(xa, yb, 0), V(xa, ya, 0), V(xa, ya, h), V(xa, yb, h));
    const auto floorRect = [&](double x0, double x1, double y0, double y1) {
      if (x1 - x0 > 1e-9 && y1 - y0 > 1e-9) quad(tris, V(x0, y0, 0), V(x1, y0, 0), V(x1, y1, 0), V(x0, y1, 0));
    };
    floorRect(cx0, xa, cy0, cy1);
    floorRect(xb, cx1, cy0, cy1);
    floorRect(xa, xb, cy0, ya);
    floorRect(xa, xb, yb, cy1);
  };
  // Pyramids: the corridor's field.
  {
    const Field& f = fields[0];
    rough_.x0 = f.x0, rough_.y0 = f.y0, rough_.nx = 8, rough_.ny = 8, rough_.pitch_m = 0.1;
    rough_.height_m = 0.5 * rough_.pitch_m * std::sqrt(1.25);
    const std::vector<Triangle> tris = rough_.triangles(0);
    addField(f, "square pyramids, pitch 0.1 m, height 0.0559 m", tris);
  }
  // Ridges: triangular prisms, crests along x (the path) or along y, gable ends vertical.
  for (const bool along : {true, false}) {
    const Field& f = fields[along ? 1 : 2];
    std::vector<Triangle> tris, ends;
    const double h = y.ridge_height_m;
    const double a0 = along ? f.y0 : f.x0, a1 = along ? f.y1 : f.x1;  // across the crests
    const double l0 = along ? f.x0 : f.y0, l1 = along ? f.x1 : f.y1;  // along them
    const auto at = [along](double across, double length, double z) { return along ? V(length, across, z) : V(across, length, z); };
    for (double a = a0; a + rp <= a1 + 1e-9; a += rp) {
      const double m = a + 0.5 * rp;
      quad(tris, at(a, l0, 0), at(a, l1, 0), at(m, l1, h), at(m, l0, h));
      quad(tris, at(m, l0, h), at(m, l1, h), at(a + rp, l1, 0), at(a + rp, l0, 0));
      ends.push_back({at(a, l0, 0), at(a + rp, l0, 0), at(m, l0, h), 0});
      ends.push_back({at(a, l1, 0), at(a + rp, l1, 0), at(m, l1, h), 0});
    }
    char text[160];
    std::snprintf(text, sizeof text, "triangular ridges, crests along %s, pitch %.3f m, height %.3f m", along ? "x" : "y", rp, h);
    addField(f, text, tris);
    // The gable ends: upright triangles, drawn as a surface of their own.
    Surface side;
    side.name = f.name + " ends";
    side.kind = SurfaceKind::kBoxSide;
    for (const Triangle& t : ends) side.polygons.push_back({t.a, t.b, t.c});
    for (auto& poly : side.polygons) {  // the end at l0 faces back along the crests, the other forward
      const double l = along ? poly[0].x() : poly[0].y();
      const V outward = (l > l0 + 1e-9 ? 1.0 : -1.0) * (along ? V::UnitX() : V::UnitY());
      if (newellNormal(poly).dot(outward) < 0) std::reverse(poly.begin(), poly.end());
    }
    addSurface(std::move(side));
  }
  // Blocks: one square block per cell, centred.
  {
    const Field& f = fields[3];
    std::vector<Triangle> tris;
    const double w = y.block_side_m, m = 0.5 * (bp - w);
    for (double x = f.x0; x + bp <= f.x1 + 1e-9; x += bp) {
      for (double yy = f.y0; yy + bp <= f.y1 + 1e-9; yy += bp) boxInCell(tris, x, x + bp, yy, yy + bp, x + m, x + m + w, yy + m, yy + m + w, y.block_height_m);
    }
    char text[160];
    std::snprintf(text, sizeof text, "square blocks, side %.3f m, height %.3f m, one per %.3f m cell", w, y.block_height_m, bp);
    addField(f, text, tris);
  }
  // Stones: a box of random size at a random place in each cell.
  {
    const Field& f = fields[4];
    std::vector<Triangle> tris;
    std::mt19937_64 rng(y.stone_seed);
    std::uniform_real_distribution<double> side(y.stone_min_side_m, y.stone_max_side_m), height(y.stone_min_height_m, y.stone_max_height_m),
        unit(0.0, 1.0);
    for (double x = f.x0; x + sp <= f.x1 + 1e-9; x += sp) {
      for (double yy = f.y0; yy + sp <= f.y1 + 1e-9; yy += sp) {
        const double wx = side(rng), wy = side(rng), h = height(rng);
        const double xa = x + unit(rng) * (sp - wx), ya = yy + unit(rng) * (sp - wy);
        boxInCell(tris, x, x + sp, yy, yy + sp, xa, xa + wx, ya, ya + wy, h);
      }
    }
    char text[200];
    std::snprintf(text, sizeof text, "stones: one box per %.3f m cell, sides %.3f-%.3f m, heights %.3f-%.3f m, seed %llu", sp,
                  y.stone_min_side_m, y.stone_max_side_m, y.stone_min_height_m, y.stone_max_height_m,
                  static_cast<unsigned long long>(y.stone_seed));
    addField(f, text, tris);
  }
  moving_.start_frame = moving_.end_frame = 0;
  moving_.size = V::Zero();
}

CorridorScene::CorridorScene(CorridorParams params) : params_(std::move(params)) {
  validate(params_);
  using V = Eigen::Vector3d;
  const double x_begin = -1.0, x_end = 10.0, half_width = 1.5, wall_h = 2.5;

  // Orients a polygon so that its Newell normal points along `outward`.
  auto oriented = [](std::vector<V> poly, const V& outward) {
    if (newellNormal(poly).dot(outward) < 0) std::reverse(poly.begin(), poly.end());
    return poly;
  };
  auto planar = [&](const std::string& name, SurfaceKind kind, std::vector<std::vector<V>> polys,
                    const V& outward, bool moving = false) {
    Surface s;
    s.name = name;
    s.kind = kind;
    for (auto& p : polys) s.polygons.push_back(oriented(std::move(p), outward));
    s.moving = moving;
    return addSurface(std::move(s));
  };
  auto rect_xy = [](double xa, double xb, double ya, double yb, double z) {
    return std::vector<V>{V(xa, ya, z), V(xb, ya, z), V(xb, yb, z), V(xa, yb, z)};
  };

  // Rough patch geometry first: the floor has a hole under it.
  rough_.x0 = 1.4;
  rough_.y0 = 0.5;
  rough_.nx = 8;
  rough_.ny = 8;
  rough_.pitch_m = 0.1;
  rough_.height_m = 0.5 * rough_.pitch_m * std::sqrt(1.25);  // area ratio exactly 1.5
  const double px1 = rough_.x0 + rough_.nx * rough_.pitch_m;
  const double py1 = rough_.y0 + rough_.ny * rough_.pitch_m;

  const auto addWalls = [&] {
    planar("left wall", SurfaceKind::kWall,
           {{V(x_begin, half_width, 0), V(x_end, half_width, 0), V(x_end, half_width, wall_h), V(x_begin, half_width, wall_h)}},
           -V::UnitY());
    planar("right wall", SurfaceKind::kWall,
           {{V(x_begin, -half_width, 0), V(x_end, -half_width, 0), V(x_end, -half_width, wall_h), V(x_begin, -half_width, wall_h)}},
           V::UnitY());
    planar("end wall", SurfaceKind::kWall,
           {{V(x_end, -half_width, 0), V(x_end, half_width, 0), V(x_end, half_width, wall_h), V(x_end, -half_width, wall_h)}},
           -V::UnitX());
  };
  if (params_.layout == Layout::kRoughYard) {
    buildRoughYard(x_begin, x_end, half_width);
    addWalls();
    return;
  }
  planar("floor", SurfaceKind::kFloor,
         {rect_xy(x_begin, rough_.x0, -half_width, half_width, 0),
          rect_xy(px1, x_end, -half_width, half_width, 0),
          rect_xy(rough_.x0, px1, -half_width, rough_.y0, 0),
          rect_xy(rough_.x0, px1, py1, half_width, 0)},
         V::UnitZ());
  addWalls();

  // Ramps on the right, rising along +x towards the walker's direction of travel.
  const double ramp_angles[] = {5, 15, 25, 35, 45};
  const double run = 0.6, ya = -1.3, yb = -0.5;
  for (int i = 0; i < 5; ++i) {
    const double x0 = 1.5 + 1.2 * i;
    const double h = run * std::tan(ramp_angles[i] * kDeg);
    const std::string tag = "ramp " + std::to_string(static_cast<int>(ramp_angles[i])) + " deg";
    planar(tag, SurfaceKind::kRamp,
           {{V(x0, ya, 0), V(x0 + run, ya, h), V(x0 + run, yb, h), V(x0, yb, 0)}},
           V(-std::sin(ramp_angles[i] * kDeg), 0, std::cos(ramp_angles[i] * kDeg)));
    planar(tag + " inner side", SurfaceKind::kRampSide,
           {{V(x0, yb, 0), V(x0 + run, yb, 0), V(x0 + run, yb, h)}}, V::UnitY());
    planar(tag + " outer side", SurfaceKind::kRampSide,
           {{V(x0, ya, 0), V(x0 + run, ya, 0), V(x0 + run, ya, h)}}, -V::UnitY());
    planar(tag + " back", SurfaceKind::kRampSide,
           {{V(x0 + run, ya, 0), V(x0 + run, yb, 0), V(x0 + run, yb, h), V(x0 + run, ya, h)}},
           V::UnitX());
  }

  // Rough pyramid field on the left.
  {
    Surface s;
    s.name = "rough patch";
    s.kind = SurfaceKind::kRough;
    s.normal = V::UnitZ();
    s.roughness = rough_.exactAreaRatio();
    s.description = "square pyramids, pitch 0.1 m";
    s.polygons.push_back(oriented(rect_xy(rough_.x0, px1, rough_.y0, py1, 0), V::UnitZ()));
    const int id = addSurface(std::move(s));
    for (const Triangle& t : rough_.triangles(id)) static_triangles_.push_back(t);
  }

  // A static box on the left.
  auto add_box = [&](const std::string& name, const V& lo, const V& hi, bool moving) {
    planar(name + " top", SurfaceKind::kBoxTop, {boxFace(lo, hi, 2, true)}, V::UnitZ(), moving);
    planar(name + " -x face", SurfaceKind::kBoxSide, {boxFace(lo, hi, 0, false)}, -V::UnitX(), moving);
    planar(name + " +x face", SurfaceKind::kBoxSide, {boxFace(lo, hi, 0, true)}, V::UnitX(), moving);
    planar(name + " -y face", SurfaceKind::kBoxSide, {boxFace(lo, hi, 1, false)}, -V::UnitY(), moving);
    planar(name + " +y face", SurfaceKind::kBoxSide, {boxFace(lo, hi, 1, true)}, V::UnitY(), moving);
  };
  add_box("box", V(4.6, 0.6, 0), V(5.0, 1.0, 0.5), false);

  // Staircase on the left: four 17 cm risers and 30 cm treads, ascending along +x.
  {
    const double x0 = 6.0, y0 = 0.4, y1 = 1.4, rise = 0.17, going = 0.30;
    const int steps = 4;
    std::vector<std::vector<V>> inner_side, outer_side;
    for (int k = 0; k < steps; ++k) {
      const double xa = x0 + k * going, xb = xa + going, z0 = k * rise, z1 = z0 + rise;
      planar("stair riser " + std::to_string(k + 1), SurfaceKind::kStairRiser,
             {{V(xa, y0, z0), V(xa, y1, z0), V(xa, y1, z1), V(xa, y0, z1)}}, -V::UnitX());
      planar("stair tread " + std::to_string(k + 1), SurfaceKind::kStairTread,
             {rect_xy(xa, xb, y0, y1, z1)}, V::UnitZ());
      inner_side.push_back(oriented({V(xa, y0, 0), V(xb, y0, 0), V(xb, y0, z1), V(xa, y0, z1)}, -V::UnitY()));
      outer_side.push_back(oriented({V(xa, y1, 0), V(xb, y1, 0), V(xb, y1, z1), V(xa, y1, z1)}, V::UnitY()));
    }
    const double xe = x0 + steps * going, ze = steps * rise;
    planar("stair back", SurfaceKind::kStairSide,
           {{V(xe, y0, 0), V(xe, y1, 0), V(xe, y1, ze), V(xe, y0, ze)}}, V::UnitX());
    planar("stair inner side", SurfaceKind::kStairSide, inner_side, -V::UnitY());
    planar("stair outer side", SurfaceKind::kStairSide, outer_side, V::UnitY());
  }

  // The moving box: in the walking path, then it slides left out of the way.
  moving_.size = V(0.4, 0.4, 0.6);
  moving_.from = V(3.2, 0.0, 0.0);
  moving_.to = V(3.2, 1.0, 0.0);
  moving_.start_frame = params_.frames / 6;
  moving_.end_frame = std::max(moving_.start_frame + 1, params_.frames / 3);
  const V half(0.5 * moving_.size.x(), 0.5 * moving_.size.y(), 0);
  add_box("moving box", moving_.from - half, moving_.from + half + V(0, 0, moving_.size.z()), true);
}

const Surface& CorridorScene::surface(int id) const {
  if (id < 1 || id > static_cast<int>(surfaces_.size())) {
    throw std::out_of_range("CorridorScene::surface: no surface with id " + std::to_string(id));
  }
  return surfaces_[static_cast<std::size_t>(id - 1)];
}

Eigen::Isometry3d CorridorScene::cameraPose(int frame) const {
  if (frame < 0 || frame >= params_.frames) {
    throw std::out_of_range("CorridorScene::cameraPose: frame " + std::to_string(frame) +
                            " outside 0.." + std::to_string(params_.frames - 1));
  }
  return cameraPoseAt(frame / params_.frame_rate_hz);
}

Eigen::Isometry3d CorridorScene::cameraPoseAt(double t) const {
  const double phase = 2.0 * kPi * params_.step_frequency_hz * t;
  const Eigen::Vector3d position(params_.speed_mps * t, 0.03 * std::sin(0.5 * phase),
                                 params_.camera_height_m + params_.bob_m * std::sin(phase));
  const double yaw = params_.sway_deg * kDeg * std::sin(0.5 * phase);
  const double pitch = (params_.pitch_down_deg + 1.0 * std::sin(phase)) * kDeg;
  const double roll = 0.5 * kDeg * std::sin(0.5 * phase);
  const Eigen::Vector3d forward(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw),
                                -std::sin(pitch));
  const Eigen::Vector3d right0(std::sin(yaw), -std::cos(yaw), 0.0);
  const Eigen::Vector3d down0 = forward.cross(right0);
  Eigen::Matrix3d r;
  r.col(0) = std::cos(roll) * right0 + std::sin(roll) * down0;
  r.col(1) = -std::sin(roll) * right0 + std::cos(roll) * down0;
  r.col(2) = forward;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = r;
  pose.translation() = position;
  return pose;
}

std::vector<Triangle> CorridorScene::trianglesAt(int frame) const {
  std::vector<Triangle> all = static_triangles_;
  const Eigen::Vector3d shift = moving_.centreAt(frame) - moving_.from;
  for (Triangle t : moving_triangles_) {
    t.a += shift;
    t.b += shift;
    t.c += shift;
    all.push_back(t);
  }
  return all;
}

RayCastResult castRays(const std::vector<Triangle>& triangles, const PinholeIntrinsics& k,
                       const Eigen::Isometry3d& T_world_camera) {
  perception::validate(k);
  const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
  const auto n_pixels = static_cast<std::size_t>(k.width) * k.height;
  std::vector<double> zbuf(n_pixels, std::numeric_limits<double>::infinity());
  RayCastResult out;
  out.depth = perception::DepthImage(k.width, k.height);
  out.labels.assign(n_pixels, 0);
  out.incidence_cos.assign(n_pixels, 0.f);

  for (const Triangle& tri : triangles) {
    const Eigen::Vector3d a = T_camera_world * tri.a;
    const Eigen::Vector3d b = T_camera_world * tri.b;
    const Eigen::Vector3d c = T_camera_world * tri.c;
    const auto clipped = clipNear({a, b, c});
    if (clipped.size() < 3) continue;
    double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
    for (const auto& p : clipped) {
      const double u = k.fx * p.x() / p.z() + k.cx;
      const double v = k.fy * p.y() / p.z() + k.cy;
      umin = std::min(umin, u);
      umax = std::max(umax, u);
      vmin = std::min(vmin, v);
      vmax = std::max(vmax, v);
    }
    const int u0 = std::max(0, static_cast<int>(std::floor(umin)) - 1);
    const int u1 = std::min(k.width - 1, static_cast<int>(std::ceil(umax)) + 1);
    const int v0 = std::max(0, static_cast<int>(std::floor(vmin)) - 1);
    const int v1 = std::min(k.height - 1, static_cast<int>(std::ceil(vmax)) + 1);
    if (u0 > u1 || v0 > v1) continue;
    const Eigen::Vector3d e1 = b - a;
    const Eigen::Vector3d e2 = c - a;
    const Eigen::Vector3d normal = e1.cross(e2).normalized();
    const Eigen::Vector3d s = -a;  // ray origin (0) minus a
    const Eigen::Vector3d q = s.cross(e1);
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        // Moller-Trumbore with origin 0 and direction d = (x, y, 1): t is the depth.
        const Eigen::Vector3d d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
        const Eigen::Vector3d p = d.cross(e2);
        const double det = e1.dot(p);
        if (std::abs(det) < 1e-15) continue;
        const double inv = 1.0 / det;
        const double bu = s.dot(p) * inv;
        if (bu < 0.0 || bu > 1.0) continue;
        const double bv = d.dot(q) * inv;
        if (bv < 0.0 || bu + bv > 1.0) continue;
        const double t = e2.dot(q) * inv;
        const auto idx = static_cast<std::size_t>(v) * k.width + u;
        if (t < kNearPlane || t >= zbuf[idx]) continue;
        zbuf[idx] = t;
        out.labels[idx] = static_cast<std::uint16_t>(tri.surface_id);
        out.incidence_cos[idx] = static_cast<float>(std::abs(normal.dot(d)) / d.norm());
      }
    }
  }
  for (std::size_t i = 0; i < n_pixels; ++i) {
    if (std::isfinite(zbuf[i])) out.depth.depth_m[i] = static_cast<float>(zbuf[i]);
  }
  return out;
}

namespace {

// The projector, baseline_m to the camera's right, lights a row's surfaces in the order
// of their projector columns u - disparity; scanned from the right, a pixel whose
// projector column is not left of every lit one so far lies in a foreground's shadow.
void castProjectorShadow(perception::DepthImage& depth, double fb) {
  std::vector<float> shadowed(depth.depth_m.size(), 0.f);
  for (int v = 0; v < depth.height; ++v) {
    double lit_min = std::numeric_limits<double>::infinity();
    for (int u = depth.width - 1; u >= 0; --u) {
      const float z = depth.at(u, v);
      if (!(z > 0.f)) continue;
      const double up = u - fb / z;
      // Half a pixel of slack: a plane seen at grazing angles must not shadow itself.
      if (up >= lit_min + 0.5) {
        shadowed[static_cast<std::size_t>(v) * depth.width + u] = 1.f;
      } else {
        lit_min = std::min(lit_min, up);
      }
    }
  }
  for (std::size_t i = 0; i < shadowed.size(); ++i) {
    if (shadowed[i] > 0.f) depth.depth_m[i] = 0.f;
  }
}

// Mean of the valid disparities in the window x window box around each valid pixel
// (separable running sums of value and count), as a block-matching sensor reports it.
std::vector<double> windowMeanDisparity(const std::vector<double>& disparity, int width, int height, int window) {
  const int r = window / 2;
  const auto idx = [width](int u, int v) { return static_cast<std::size_t>(v) * width + u; };
  std::vector<double> row_sum(disparity.size(), 0.0), row_n(disparity.size(), 0.0);
  for (int v = 0; v < height; ++v) {
    double sum = 0, n = 0;
    for (int u = -r; u < width; ++u) {
      const int in = u + r, out = u - r - 1;
      if (in < width && disparity[idx(in, v)] > 0) sum += disparity[idx(in, v)], n += 1;
      if (out >= 0 && disparity[idx(out, v)] > 0) sum -= disparity[idx(out, v)], n -= 1;
      if (u >= 0) row_sum[idx(u, v)] = sum, row_n[idx(u, v)] = n;
    }
  }
  std::vector<double> mean(disparity.size(), 0.0);
  for (int u = 0; u < width; ++u) {
    double sum = 0, n = 0;
    for (int v = -r; v < height; ++v) {
      const int in = v + r, out = v - r - 1;
      if (in < height) sum += row_sum[idx(u, in)], n += row_n[idx(u, in)];
      if (out >= 0) sum -= row_sum[idx(u, out)], n -= row_n[idx(u, out)];
      if (v >= 0 && disparity[idx(u, v)] > 0 && n > 0.5) mean[idx(u, v)] = sum / n;
    }
  }
  return mean;
}

// The edge model: shadow, window-mean disparity, mixed pixels on discontinuities.
void applyEdgeModel(perception::DepthImage& depth, const KinectNoiseParams& p, double fb, std::mt19937_64& rng) {
  if (p.projector_shadow) castProjectorShadow(depth, fb);
  if (p.edge_window_px <= 0) return;
  const int w = depth.width, h = depth.height;
  std::vector<double> disparity(depth.depth_m.size(), 0.0);
  for (std::size_t i = 0; i < disparity.size(); ++i) {
    const float z = depth.depth_m[i];
    if (z > 0.f) disparity[i] = fb / z;
  }
  const std::vector<double> mean = windowMeanDisparity(disparity, w, h, p.edge_window_px);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * w + u;
      const double mix_draw = uniform01(rng), where = uniform01(rng);
      if (!(disparity[i] > 0)) continue;
      double d = mean[i];
      double lo = disparity[i], hi = disparity[i];
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          const double n = disparity[static_cast<std::size_t>(vv) * w + uu];
          if (n > 0) lo = std::min(lo, n), hi = std::max(hi, n);
        }
      }
      if (hi - lo > p.edge_jump_px && mix_draw < p.flying_pixel_probability) d = lo + where * (hi - lo);
      depth.depth_m[i] = static_cast<float>(fb / d);
    }
  }
}

}  // namespace

void applyKinectNoise(perception::DepthImage& depth, const std::vector<float>& incidence_cos,
                      const KinectNoiseParams& p, double fx, std::uint64_t seed, int frame) {
  std::mt19937_64 rng(mix(seed ^ mix(static_cast<std::uint64_t>(frame) + 1)));
  const double fb = fx * p.baseline_m;  // disparity (px) = fb / z
  {
    // Its own stream, so the per-pixel noise below is the same with the edge model on or off.
    std::mt19937_64 edge_rng(mix(seed ^ mix(static_cast<std::uint64_t>(frame) + 1) ^ 0xED6EULL));
    applyEdgeModel(depth, p, fb, edge_rng);
  }
  const double cos_start = std::cos(p.dropout_start_deg * kDeg);
  for (std::size_t i = 0; i < depth.depth_m.size(); ++i) {
    // Draw the same number of variates per pixel so pixels do not shift each other's noise.
    const double g = gaussian(rng);
    const double drop = uniform01(rng);
    double z = depth.depth_m[i];
    if (!(z > 0)) continue;
    const double c = incidence_cos[i];
    if (c < cos_start) {
      const double angle = std::acos(std::clamp(c, 0.0, 1.0)) / kDeg;
      const double frac = (angle - p.dropout_start_deg) / (p.dropout_full_deg - p.dropout_start_deg);
      if (drop < frac) {
        depth.depth_m[i] = 0.f;
        continue;
      }
    }
    z += p.axial_sigma_at_1m_m * z * z * g;
    if (p.disparity_subpixel > 0 && z > 0) {
      const double disparity = fb / z;
      const double quantised = std::round(disparity / p.disparity_subpixel) * p.disparity_subpixel;
      z = quantised > 0 ? fb / quantised : 0.0;
    }
    depth.depth_m[i] = (z > 0 && z <= p.max_depth_m) ? static_cast<float>(z) : 0.f;
  }
}

RenderedFrame CorridorScene::render(int frame) const {
  RenderedFrame out;
  out.T_world_camera = cameraPose(frame);
  const PinholeIntrinsics& k = params_.intrinsics;
  RayCastResult rc = castRays(trianglesAt(frame), k, out.T_world_camera);
  out.exact_depth = rc.depth;
  out.depth = rc.depth;
  if (params_.noise == NoiseModel::kKinect) {
    applyKinectNoise(out.depth, rc.incidence_cos, params_.kinect, k.fx, params_.seed, frame);
  }
  out.labels = std::move(rc.labels);
  // Colour: Lambertian shading of each surface's base colour, a 0.5 m checker on the floor.
  out.colour.assign(out.labels.size(), {0, 0, 0});
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const auto idx = static_cast<std::size_t>(v) * k.width + u;
      const int id = out.labels[idx];
      if (id == 0) continue;
      const Surface& s = surfaces_[static_cast<std::size_t>(id - 1)];
      auto base = baseColour(s.kind);
      double shade = 0.35 + 0.65 * rc.incidence_cos[idx];
      if (s.kind == SurfaceKind::kFloor) {
        const Eigen::Vector3d pw =
            out.T_world_camera * perception::backProject(k, u, v, out.exact_depth.depth_m[idx]);
        const long cell = static_cast<long>(std::floor(pw.x() / 0.5)) + static_cast<long>(std::floor(pw.y() / 0.5));
        if (cell % 2 != 0) shade *= 0.8;
      }
      for (int ch = 0; ch < 3; ++ch) {
        out.colour[idx][static_cast<std::size_t>(ch)] =
            static_cast<std::uint8_t>(std::clamp(base[static_cast<std::size_t>(ch)] * shade, 0.0, 255.0));
      }
    }
  }
  return out;
}

double bruteForceAreaRatio(const PyramidField& f, int n) {
  if (n < 1) throw std::invalid_argument("bruteForceAreaRatio: n must be >= 1");
  const double w = f.nx * f.pitch_m, h = f.ny * f.pitch_m;
  const double dx = w / n, dy = h / n;
  auto pt = [&](int i, int j) {
    const double x = f.x0 + i * dx, y = f.y0 + j * dy;
    return Eigen::Vector3d(x, y, f.heightAt(x, y));
  };
  double area = 0.0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const auto p00 = pt(i, j), p10 = pt(i + 1, j), p11 = pt(i + 1, j + 1), p01 = pt(i, j + 1);
      area += 0.5 * (p10 - p00).cross(p11 - p00).norm();
      area += 0.5 * (p11 - p00).cross(p01 - p00).norm();
    }
  }
  return area / (w * h);
}

}  // namespace mobmap::sim
