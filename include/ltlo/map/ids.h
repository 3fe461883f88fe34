#pragma once
/// Typed ids of keyframes, map points and maps. Issued by an IdSource that the Atlas shares with
/// all its maps (so ids stay unique when maps merge); no static counters.
#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <ostream>

namespace ltlo::map {

namespace detail {
/// One id type per Tag: a KeyFrameId cannot be passed where a MapPointId is expected.
template <typename Tag>
struct TypedId {
  static constexpr std::uint64_t kInvalid = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t value = kInvalid;  ///< issue order: a larger value was issued later

  constexpr TypedId() = default;
  constexpr explicit TypedId(std::uint64_t v) : value(v) {}
  constexpr bool valid() const { return value != kInvalid; }
  friend constexpr bool operator==(TypedId a, TypedId b) { return a.value == b.value; }
  friend constexpr bool operator!=(TypedId a, TypedId b) { return a.value != b.value; }
  friend constexpr bool operator<(TypedId a, TypedId b) { return a.value < b.value; }
  friend std::ostream& operator<<(std::ostream& os, TypedId id) {
    return id.valid() ? (os << Tag::kPrefix << id.value) : (os << Tag::kPrefix << "none");
  }
};
struct KeyFrameTag {
  static constexpr const char* kPrefix = "kf";
};
struct MapPointTag {
  static constexpr const char* kPrefix = "mp";
};
struct MapTag {
  static constexpr const char* kPrefix = "map";
};
}  // namespace detail

using KeyFrameId = detail::TypedId<detail::KeyFrameTag>;
using MapPointId = detail::TypedId<detail::MapPointTag>;
using MapId = detail::TypedId<detail::MapTag>;

/// Issues ids in increasing order. Thread-safe (atomic counters, no lock).
class IdSource {
 public:
  KeyFrameId nextKeyFrameId() { return KeyFrameId(next_keyframe_.fetch_add(1)); }
  MapPointId nextMapPointId() { return MapPointId(next_point_.fetch_add(1)); }
  MapId nextMapId() { return MapId(next_map_.fetch_add(1)); }
  /// Makes every later id larger than the given ones (invalid ids are ignored): a loaded atlas
  /// continues above the ids of its file, so new objects never collide with loaded ones.
  void reserveAbove(KeyFrameId kf, MapPointId point, MapId map) {
    raiseTo(next_keyframe_, kf);
    raiseTo(next_point_, point);
    raiseTo(next_map_, map);
  }
  /// The next ids to be issued (a run's state in the atlas file: a resumed run issues the ids the
  /// saved run would have issued next, culled and merged objects' ids included).
  struct Counters {
    std::uint64_t keyframe = 0;
    std::uint64_t point = 0;
    std::uint64_t map = 0;
  };
  Counters counters() const { return {next_keyframe_.load(), next_point_.load(), next_map_.load()}; }
  /// Only before the ids are shared with other threads (a loaded atlas being restored).
  void restore(const Counters& counters) {
    next_keyframe_.store(counters.keyframe);
    next_point_.store(counters.point);
    next_map_.store(counters.map);
  }

 private:
  template <typename Id>
  static void raiseTo(std::atomic<std::uint64_t>& next, Id id) {
    if (!id.valid()) return;
    std::uint64_t current = next.load();
    while (current <= id.value && !next.compare_exchange_weak(current, id.value + 1)) {
    }
  }

  std::atomic<std::uint64_t> next_keyframe_{0};
  std::atomic<std::uint64_t> next_point_{0};
  std::atomic<std::uint64_t> next_map_{0};
};

}  // namespace ltlo::map

namespace std {
template <typename Tag>
struct hash<ltlo::map::detail::TypedId<Tag>> {
  std::size_t operator()(ltlo::map::detail::TypedId<Tag> id) const noexcept {
    return std::hash<std::uint64_t>()(id.value);
  }
};
}  // namespace std
