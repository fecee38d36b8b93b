#pragma once
// A recording's TF tree: each frame's parent and the transform to it, fixed (from
// /tf_static) or sampled over time (from /tf), and the pose of one frame in another at
// a given time, composed through their common ancestor with the semantics of tf2's
// BufferCore: a sampled transform is interpolated between the two samples around the
// time (linearly in translation, spherically in rotation) and never extrapolated.

#include "mobmap/mapping/pose_samples.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace mobmap::sources {

/// The tree itself is wrong: a cycle, a frame with two parents, a frame its own parent,
/// a transform that is not a rotation and a translation.
class TfError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TfEdge {
  std::string parent, child;
  bool is_static = false;
  std::size_t samples = 0;
};

class TfTree {
 public:
  /// Adds `T_parent_child` (the child frame's pose in its parent's). A static transform
  /// replaces an earlier one; a sampled one is kept by its stamp (samples that arrive out
  /// of stamp order are appended and sorted once, by sortSamples()). TfError when the child
  /// already has another parent, is its own parent, or the rotation is not a unit
  /// quaternion (within 1e-3) or a value is not finite.
  void add(const std::string& parent, const std::string& child, std::int64_t stamp_ns, const Eigen::Vector3d& t,
           const Eigen::Quaterniond& q, bool is_static);

  /// Puts every link's samples in stamp order (equal stamps keep the order they were
  /// added in): O(n log n) once, however the samples arrived. lookup() needs it after
  /// out-of-order samples.
  void sortSamples();
  /// True when every link's samples are in stamp order (no sortSamples() pending).
  [[nodiscard]] bool sorted() const { return unsorted_links_ == 0; }

  /// Forgets the sampled transforms older than `stamp_ns`, keeping on each link the last
  /// sample before it (so a lookup at `stamp_ns` still interpolates): a live buffer's
  /// bound. Needs sorted samples (std::logic_error otherwise).
  void forgetBefore(std::int64_t stamp_ns);

  /// `source`'s pose in `target` at `stamp_ns`: nullopt (with `why`) when a sampled
  /// transform on the way has no samples on both sides of the stamp within
  /// `max_gap_ns` of each other (or one at the stamp). TfError when a frame is missing
  /// from the tree, the two are not connected, or the way up from one meets a cycle.
  /// std::logic_error when samples were added out of order since the last sortSamples().
  [[nodiscard]] std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source,
                                                        std::int64_t stamp_ns, std::int64_t max_gap_ns,
                                                        std::string* why = nullptr) const;

  [[nodiscard]] bool has(const std::string& frame) const;
  /// Every frame named by a transform, sorted.
  [[nodiscard]] std::vector<std::string> frames() const;
  /// Every parent -> child link, sorted by child.
  [[nodiscard]] std::vector<TfEdge> edges() const;
  /// The frames from `frame` up to its root, `frame` first. TfError on a cycle.
  [[nodiscard]] std::vector<std::string> chainToRoot(const std::string& frame) const;
  /// Bytes held by the samples.
  [[nodiscard]] std::size_t memoryBytes() const;

 private:
  using Sample = mapping::PoseSample;
  struct Link {
    std::string parent;
    bool is_static = false;
    std::vector<Sample> samples;  // sorted by stamp unless `sorted` is false
    bool sorted = true;
  };
  std::optional<Eigen::Isometry3d> linkAt(const std::string& child, const Link& link, std::int64_t stamp_ns,
                                          std::int64_t max_gap_ns, std::string* why) const;
  std::map<std::string, Link> links_;  // by child frame
  std::size_t unsorted_links_ = 0;
};

}  // namespace mobmap::sources
