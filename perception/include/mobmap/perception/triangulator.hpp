#pragma once

namespace mobmap::perception {

/// Who builds the Delaunay triangulation the roughness is measured on. kCgal is CGAL's
/// Delaunay_triangulation_2, the reference. kOwn is the library's incremental
/// triangulation, 1.6x faster on the segments of real frames: it makes the same exact
/// decisions (a floating-point filter, CGAL's exact predicates when it cannot decide),
/// so it gives the same triangles unless four or more points lie on one circle, where
/// which diagonal is drawn depends on the order of insertion (in CGAL as well).
enum class Triangulator { kOwn, kCgal };

}  // namespace mobmap::perception
