#include "mobmap/sources/tf_tree.hpp"

#include "mobmap/mapping/pose_samples.hpp"

#include "words.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace mobmap::sources {

void TfTree::add(const std::string& parent, const std::string& child, std::int64_t stamp_ns, const Eigen::Vector3d& t,
                 const Eigen::Quaterniond& q, bool is_static) {
  if (parent.empty() || child.empty()) throw TfError("a transform with an empty frame name (parent \"" + parent + "\", child \"" + child + "\")");
  if (parent == child) throw TfError("frame \"" + child + "\" is given as its own parent");
  if (!t.allFinite() || !q.coeffs().allFinite()) throw TfError("the transform " + parent + " -> " + child + " holds a value that is not finite");
  if (std::abs(q.norm() - 1.0) > 1e-3) {
    throw TfError("the rotation of " + parent + " -> " + child + " is not a unit quaternion (norm " + std::to_string(q.norm()) + ")");
  }
  auto [it, fresh] = links_.try_emplace(child);
  Link& link = it->second;
  if (!fresh && link.parent != parent) {
    throw TfError("frame \"" + child + "\" has two parents, \"" + link.parent + "\" and \"" + parent + "\"");
  }
  if (!fresh && link.is_static != is_static) {
    throw TfError("the transform " + parent + " -> " + child + " is published both on /tf_static and on /tf");
  }
  link.parent = parent;
  link.is_static = is_static;
  const Sample s{stamp_ns, t, q.normalized()};
  if (is_static) {
    link.samples.assign(1, s);
    return;
  }
  // Appended: a sample older than the last one marks the link for one sort (inserting
  // each in place costs quadratic time in a recording whose stamps run backwards).
  auto& v = link.samples;
  if (link.sorted && !v.empty() && stamp_ns < v.back().stamp_ns) {
    link.sorted = false;
    ++unsorted_links_;
  }
  v.push_back(s);
}

void TfTree::forgetBefore(std::int64_t stamp_ns) {
  if (unsorted_links_ != 0) throw std::logic_error("TfTree::forgetBefore needs sorted samples");
  for (auto& [child, link] : links_) {
    if (link.is_static) continue;
    auto& v = link.samples;
    const auto first_kept = std::lower_bound(v.begin(), v.end(), stamp_ns,
                                             [](const Sample& s, std::int64_t t) { return s.stamp_ns < t; });
    if (first_kept - v.begin() > 1) v.erase(v.begin(), first_kept - 1);
  }
}

void TfTree::sortSamples() {
  if (unsorted_links_ == 0) return;
  for (auto& [child, link] : links_) {
    if (link.sorted) continue;
    std::stable_sort(link.samples.begin(), link.samples.end(), [](const Sample& a, const Sample& b) { return a.stamp_ns < b.stamp_ns; });
    link.sorted = true;
  }
  unsorted_links_ = 0;
}

bool TfTree::has(const std::string& frame) const {
  if (links_.count(frame)) return true;
  return std::any_of(links_.begin(), links_.end(), [&](const auto& l) { return l.second.parent == frame; });
}

std::vector<std::string> TfTree::frames() const {
  std::set<std::string> all;
  for (const auto& [child, link] : links_) {
    all.insert(child);
    all.insert(link.parent);
  }
  return {all.begin(), all.end()};
}

std::vector<TfEdge> TfTree::edges() const {
  std::vector<TfEdge> out;
  for (const auto& [child, link] : links_) out.push_back({link.parent, child, link.is_static, link.samples.size()});
  return out;
}

std::size_t TfTree::memoryBytes() const {
  std::size_t bytes = 0;
  for (const auto& [child, link] : links_) bytes += link.samples.capacity() * sizeof(Sample) + child.size() + link.parent.size() + 96;
  return bytes;
}

std::vector<std::string> TfTree::chainToRoot(const std::string& frame) const {
  std::vector<std::string> chain{frame};
  std::set<std::string> seen{frame};
  for (auto it = links_.find(frame); it != links_.end(); it = links_.find(chain.back())) {
    const std::string& parent = it->second.parent;
    if (!seen.insert(parent).second) {
      std::string cycle = parent;
      for (auto c = std::find(chain.begin(), chain.end(), parent); c != chain.end(); ++c) {
        if (*c != parent) cycle += " -> " + *c;
      }
      throw TfError("the TF tree has a cycle: " + cycle + " -> " + parent);
    }
    chain.push_back(parent);
  }
  return chain;
}

std::optional<Eigen::Isometry3d> TfTree::linkAt(const std::string& child, const Link& link, std::int64_t stamp_ns,
                                                std::int64_t max_gap_ns, std::string* why) const {
  if (link.is_static) return mapping::poseAt(link.samples, link.samples.front().stamp_ns, 0);
  std::string link_why;
  auto T = mapping::poseAt(link.samples, stamp_ns, max_gap_ns, why ? &link_why : nullptr);
  if (!T && why) *why = link.parent + " -> " + child + " " + link_why;
  return T;
}

std::optional<Eigen::Isometry3d> TfTree::lookup(const std::string& target, const std::string& source, std::int64_t stamp_ns,
                                                std::int64_t max_gap_ns, std::string* why) const {
  if (unsorted_links_ != 0) throw std::logic_error("TfTree::lookup: samples were added out of stamp order; call sortSamples() first");
  for (const std::string* f : {&target, &source}) {
    if (!has(*f)) {
      throw TfError("frame \"" + *f + "\" is not in the TF tree (its frames: " + listed(frames()) + ")");
    }
  }
  const auto up_source = chainToRoot(source);
  const auto up_target = chainToRoot(target);
  if (up_source.back() != up_target.back()) {
    throw TfError("frames \"" + source + "\" and \"" + target + "\" are not connected: their roots are \"" + up_source.back() +
                  "\" and \"" + up_target.back() + "\" (is /tf_static missing from the recording?)");
  }
  // The common ancestor: the first frame up from the source that is on the target's way up.
  const std::set<std::string> on_target(up_target.begin(), up_target.end());
  std::size_t meet = 0;
  while (!on_target.count(up_source[meet])) ++meet;
  const std::string& ancestor = up_source[meet];
  // T_ancestor_frame composed up a chain.
  auto upTo = [&](const std::vector<std::string>& chain) -> std::optional<Eigen::Isometry3d> {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (std::size_t i = 0; chain[i] != ancestor; ++i) {
      const auto step = linkAt(chain[i], links_.at(chain[i]), stamp_ns, max_gap_ns, why);
      if (!step) return std::nullopt;
      T = *step * T;
    }
    return T;
  };
  const auto T_ancestor_source = upTo(up_source);
  if (!T_ancestor_source) return std::nullopt;
  const auto T_ancestor_target = upTo(up_target);
  if (!T_ancestor_target) return std::nullopt;
  return T_ancestor_target->inverse() * *T_ancestor_source;
}

}  // namespace mobmap::sources
