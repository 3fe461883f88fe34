// The boxes' schedule: the scenario's events, --occlusion-at, --occluded-start, --three-movers and
// --plain-movers; their poses over time.
#include <algorithm>
#include <cmath>

#include "ltlo/sim/scene.h"
#include "mover_schedule.h"
#include "scene_layout.h"

namespace ltlo::sim {
namespace {

struct Profile {
  double share, hold_min_s, hold_max_s;
  int max_boxes;
};

// Occluded start: how far and how fast its box leaves after t_move_s (gone 1.5 s later).
constexpr double kStartLeaveS = 1.5;
constexpr double kStartAwayGrowM = 1.0, kStartAwaySlideM = 3.5;     // pushed away: further, then aside
constexpr double kStartTowardsM = 0.35, kStartTowardsSlideM = 2.5;  // pulled to 0.35 m, then aside
constexpr double kStartClearS = 5.0;                                // scenario events before this are dropped

// Pose in the floor frame of a box ahead of the camera: near face distance_m from the camera,
// lateral_m to the left, standing on the floor.
SE3 boxAheadInFloor(const DynamicBox& b, double distance_m, double lateral_m) {
  const Vec3 t_b_c = SimOptions::T_b_c().translation();
  return SE3(Quat::Identity(), Vec3(t_b_c.x() + distance_m + 0.5 * b.size_m.x(), lateral_m, 0.5 * b.size_m.z()));
}

// The occluded start's box: still in the floor frame until t_move_s, then pushed away (its
// distance grows by 1 m over 1 s while it slides 3.5 m aside from 0.3 s) or pulled towards the
// robot (to 0.35 m over 0.7 s, then slid 2.5 m aside from 0.6 s).
SE3 startBoxInFloor(const DynamicBox& b, double t_s) {
  const double u = t_s - b.t_move_s;
  if (b.start_move == StartMove::kAway)
    return boxAheadInFloor(b, b.distance_m + kStartAwayGrowM * smoothstep(u / 1.0),
                           b.lateral_m + b.side * kStartAwaySlideM * smoothstep((u - 0.3) / 1.2));
  const double closest = std::min(b.distance_m, kStartTowardsM);
  return boxAheadInFloor(b, b.distance_m + (closest - b.distance_m) * smoothstep(u / 0.7),
                         b.lateral_m + b.side * kStartTowardsSlideM * smoothstep((u - 0.6) / 0.9));
}

// Largest x in [lo, hi] with decreasing(x) >= target by bisection (lo when none, hi when all).
template <typename F>
double solveDecreasing(F decreasing, double target, double lo, double hi) {
  if (decreasing(lo) < target) return lo;
  if (decreasing(hi) >= target) return hi;
  for (int k = 0; k < 40; ++k) {
    const double mid = 0.5 * (lo + hi);
    (decreasing(mid) >= target ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace

double clearTimeS(const SimOptions& options) { return std::min(3.0, 0.1 * options.duration_s); }

void dropBoxesOverlapping(Scene* scene, double t0_s, double t1_s, bool carried_too) {
  std::vector<DynamicBox>& boxes = scene->boxes;
  boxes.erase(std::remove_if(boxes.begin(), boxes.end(),
                             [&](const DynamicBox& b) {
                               return (carried_too || !b.carried) && b.t_in_s <= t1_s && b.t_out_s >= t0_s;
                             }),
              boxes.end());
}

void Scene::scheduleOcclusions(const SimOptions& options) {
  Scene& scene = *this;
  scene.boxes.clear();
  scene.walkers.clear();
  scene.doors.clear();
  scene.door_frames.clear();
  std::mt19937_64 event_rng(options.seed * 6364136223846793005ULL + 1442695040888963407ULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(event_rng); };
  const double duration = options.duration_s;
  const double t_clear = clearTimeS(options);
  auto dynamicTexture = [&]() { return kFirstDynamic + static_cast<int>(unit(event_rng) * kDynamicTextures); };
  if (options.scenario == Scenario::kCarried) {
    DynamicBox b;
    b.size_m = Vec3(uniform(0.4, 0.6), uniform(0.75, 0.95), uniform(0.8, 0.95));
    b.texture = dynamicTexture();
    b.t_in_s = std::max(t_clear, 0.2 * duration);
    b.t_out_s = 0.85 * duration;
    b.distance_m = uniform(0.65, 0.9);
    b.lateral_m = uniform(-0.15, 0.15);
    b.side = unit(event_rng) < 0.5 ? -1.0 : 1.0;
    b.carried = true;
    b.enter_s = std::min(kEnterS, 0.25 * (b.t_out_s - b.t_in_s));
    scene.boxes.push_back(b);
  } else if (options.scenario != Scenario::kStatic) {
    const Profile profile = options.scenario == Scenario::kStlo   ? Profile{0.17, 2.0, 4.0, 1}
                            : options.scenario == Scenario::kMtlo ? Profile{0.33, 3.0, 6.0, 2}
                                                                  : Profile{0.72, 8.0, 16.0, 3};
    // Per event about hold + kEnterS seconds are largely occluded; gaps fill the rest.
    const double occluded_mean = 0.5 * (profile.hold_min_s + profile.hold_max_s) + kEnterS;
    const double gap_mean = std::max(0.5, occluded_mean * (1.0 - profile.share) / profile.share - kEnterS);
    double t = t_clear;
    bool first = true;
    int event = 0;
    while (true) {
      const double gap = first ? uniform(0.0, 1.0) * gap_mean : uniform(0.6, 1.4) * gap_mean;
      first = false;
      const double t_in = t + gap;
      if (t_in >= duration) break;
      const double t_out = t_in + 2 * kEnterS + uniform(profile.hold_min_s, profile.hold_max_s);
      const int num_boxes = 1 + static_cast<int>(unit(event_rng) * profile.max_boxes);
      DynamicBox front;
      front.size_m = Vec3(uniform(0.5, 0.8), uniform(0.75, 1.1), uniform(0.75, 1.1));
      front.texture = dynamicTexture();
      front.t_in_s = t_in;
      front.t_out_s = t_out;
      front.distance_m = uniform(0.55, 1.05);
      front.lateral_m = uniform(-0.3, 0.3);
      front.side = unit(event_rng) < 0.5 ? -1.0 : 1.0;
      front.sway_phase = uniform(0.0, 2.0 * M_PI);
      front.event = event++;
      scene.boxes.push_back(front);
      for (int k = 1; k < num_boxes; ++k) {  // further boxes behind, peeking out at the sides
        DynamicBox b = front;
        b.size_m = Vec3(uniform(0.5, 0.8), uniform(0.5, 1.0), uniform(0.6, 1.2));
        b.texture = dynamicTexture();
        b.t_in_s = t_in + uniform(0.0, 2.0);
        b.t_out_s = std::max(b.t_in_s + 2 * kEnterS + 1.0, t_out - uniform(0.0, 2.0));
        b.distance_m = front.distance_m + front.size_m.x() + uniform(0.2, 0.6);
        const double sign = k == 1 ? (unit(event_rng) < 0.5 ? -1.0 : 1.0)
                                   : -1.0 * (scene.boxes.back().lateral_m > front.lateral_m ? 1 : -1);
        b.lateral_m = front.lateral_m + sign * uniform(0.55, 0.9);
        b.side = sign;
        b.sway_phase = uniform(0.0, 2.0 * M_PI);
        scene.boxes.push_back(b);
      }
      t = t_out;
    }
  }
  addCrossingEvents(options);
  addOccludedStart(options, this);
  addThreeMovers(options, this);
  scheduleWalkers(options, this);
  scheduleDoors(options, this);
  applyPlainMovers(options, this);
}

void Scene::addCrossingEvents(const SimOptions& options) {
  for (size_t k = 0; k < options.occlusion_at_s.size(); ++k) {
    // Own stream per event, so the regular schedule's draws stay what they were.
    std::mt19937_64 rng(options.seed * 2862933555777941757ULL + 3037000493ULL * (k + 1));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
    DynamicBox b;
    b.size_m = Vec3(uniform(0.5, 0.8), uniform(0.75, 1.1), uniform(0.75, 1.1));
    b.texture = kFirstDynamic + static_cast<int>(unit(rng) * kDynamicTextures);
    b.t_in_s = options.occlusion_at_s[k];
    b.t_out_s = b.t_in_s + 2 * kEnterS + uniform(2.0, 4.0);
    b.distance_m = uniform(0.55, 1.05);
    b.lateral_m = uniform(-0.2, 0.2);
    b.side = unit(rng) < 0.5 ? -1.0 : 1.0;
    b.crosses = true;
    b.sway_phase = uniform(0.0, 2.0 * M_PI);
    b.event = 0;  // numbered after the events before it
    for (const DynamicBox& other : boxes) b.event = std::max(b.event, other.event + 1);
    // Regular boxes present while it crosses would stand in its way: they are dropped.
    boxes.erase(std::remove_if(boxes.begin(), boxes.end(),
                               [&](const DynamicBox& other) {
                                 return !other.carried && other.t_in_s < b.t_out_s && other.t_out_s > b.t_in_s;
                               }),
                boxes.end());
    boxes.push_back(b);
  }
}

void addOccludedStart(const SimOptions& options, Scene* scene) {
  if (options.occluded_start == StartMove::kNone) return;
  Draw draw(options.seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);
  DynamicBox b;
  b.size_m = Vec3(draw(0.5, 0.8), draw(0.8, 1.2), draw(0.9, 1.3));
  b.texture = draw.dynamicTexture();
  b.lateral_m = draw(-0.15, 0.15);
  b.side = draw.sign();
  b.start_move = options.occluded_start;
  b.t_move_s = draw(1.5, 3.5);
  b.t_in_s = 0.0;
  b.t_out_s = b.t_move_s + kStartLeaveS;
  // Its distance: the share of frame 0 it covers (nominal camera, no vibration) is the drawn target.
  const double target = draw(0.45, 0.75);
  const PinholeCamera camera = options.camera();
  const SE3 T_c_floor = nominalT_floor_c().inverse();
  b.distance_m = solveDecreasing(
      [&](double d) { return boxImageShare(camera, T_c_floor * boxAheadInFloor(b, d, b.lateral_m), b.size_m); }, target,
      0.3, 3.0);
  dropBoxesOverlapping(scene, 0.0, std::max(kStartClearS, b.t_out_s), true);
  scene->boxes.push_back(b);
}

double occludedStartEndS(const Scene& scene) {
  double end_s = 0.0;
  for (const DynamicBox& b : scene.boxes)
    if (b.start_move != StartMove::kNone) end_s = std::max(end_s, std::max(kStartClearS, b.t_out_s));
  return end_s;
}

void addThreeMovers(const SimOptions& options, Scene* scene) {
  if (!options.three_movers) return;
  Draw draw(options.seed * 0xD1B54A32D192ED03ULL + 0x8CB92BA72F3D8DD7ULL);
  const double t_start = std::max(clearTimeS(options), occludedStartEndS(*scene));
  const double t_end = options.duration_s + 2.0 * kEnterS;  // the lead and the carried box stay on
  dropBoxesOverlapping(scene, t_start, t_end, true);
  // Depth order from the camera: carried (near face 0.5-0.55 m, far face <= 0.9 m), crossing
  // (1.0-1.1 m, <= 1.45 m, sway 6 cm), lead (1.6-2.0 m): nothing passes through anything.
  const double carried_side = draw.sign();
  DynamicBox carried;
  carried.size_m = Vec3(draw(0.3, 0.35), draw(0.45, 0.6), draw(0.55, 0.7));
  carried.texture = draw.dynamicTexture();
  carried.distance_m = draw(0.5, 0.55);
  carried.side = carried_side;
  carried.carried = true;
  carried.t_in_s = t_start;
  carried.t_out_s = t_end;
  // To one side: as far out as leaves it the drawn 20-30 % of the view.
  const double target = draw(0.2, 0.3);
  const PinholeCamera camera = options.camera();
  const SE3 T_c_b = SimOptions::T_b_c().inverse();
  const double body_height_m = TrajectoryParams{}.body_height_m;
  const Vec3 t_b_c = SimOptions::T_b_c().translation();
  const auto carriedShare = [&](double offset_m) {
    const SE3 T_b_o(Quat::Identity(), Vec3(t_b_c.x() + carried.distance_m + 0.5 * carried.size_m.x(),
                                           carried_side * offset_m, -body_height_m + 0.5 * carried.size_m.z() + 0.05));
    return boxImageShare(camera, T_c_b * T_b_o, carried.size_m);
  };
  carried.lateral_m = carried_side * solveDecreasing(carriedShare, target, 0.0, 1.5);
  scene->boxes.push_back(carried);

  DynamicBox lead;
  lead.size_m = Vec3(draw(0.5, 0.7), draw(0.6, 0.9), draw(0.7, 1.0));
  lead.texture = draw.dynamicTexture();
  lead.distance_m = draw(1.6, 2.0);
  lead.lateral_m = -carried_side * draw(0.25, 0.45);
  lead.side = -carried_side;
  lead.sway_phase = draw(0.0, 2.0 * M_PI);
  lead.t_in_s = t_start + draw(0.0, 1.0);
  lead.t_out_s = t_end;
  scene->boxes.push_back(lead);

  // Crossing boxes one after another, held on the carried box's side above it.
  for (double t = t_start + draw(0.5, 2.0); t < options.duration_s;) {
    DynamicBox b;
    b.size_m = Vec3(draw(0.3, 0.35), draw(0.5, 0.7), draw(0.6, 0.9));
    b.texture = draw.dynamicTexture();
    b.distance_m = draw(1.0, 1.1);
    b.lateral_m = carried_side * draw(0.1, 0.35);
    b.side = draw.sign();
    b.crosses = true;
    b.sway_phase = draw(0.0, 2.0 * M_PI);
    b.t_in_s = t;
    b.t_out_s = t + 2.0 * kEnterS + draw(2.0, 4.0);
    scene->boxes.push_back(b);
    t = b.t_out_s + draw(0.5, 2.0);
  }
}

void applyPlainMovers(const SimOptions& options, Scene* scene) {
  if (!options.plain_movers) return;
  Draw draw(options.seed * 0xBF58476D1CE4E5B9ULL + 0x94D049BB133111EBULL);
  // Half of the scenario's and --occlusion-at's events (rounded up) become panels.
  std::vector<int> events;
  for (const DynamicBox& b : scene->boxes)
    if (b.event >= 0 && std::find(events.begin(), events.end(), b.event) == events.end()) events.push_back(b.event);
  for (int k = static_cast<int>(events.size()) - 1; k > 0; --k) std::swap(events[k], events[draw.index(k + 1)]);
  events.resize((events.size() + 1) / 2);
  for (DynamicBox& b : scene->boxes) {
    b.plain = true;
    b.plain_rgb = plainColour(draw);
    if (std::find(events.begin(), events.end(), b.event) == events.end()) continue;
    b.panel = true;
    // Three draws either way, so both sizes leave the colours that follow the same.
    const double thickness_m = draw(0.03, 0.05), tall_width_m = draw(1.0, 1.4), tall_height_m = draw(1.5, 2.0);
    b.size_m = options.tall_panels ? Vec3(thickness_m, tall_width_m, tall_height_m)
                                   : Vec3(thickness_m, b.size_m.y(), b.size_m.z());
  }
  for (Walker& w : scene->walkers) {
    w.plain = true;
    w.shirt_rgb = plainColour(draw);
    w.trouser_rgb = 0.6 * plainColour(draw);
  }
  for (Door& door : scene->doors) {
    door.plain = true;
    door.plain_rgb = plainColour(draw);
  }
}

std::vector<std::pair<int, SE3>> Scene::dynamicPoses(double t_s, const RobotTrajectory& trajectory) const {
  std::vector<std::pair<int, SE3>> poses;
  const Vec3 t_b_c = SimOptions::T_b_c().translation();
  for (size_t i = 0; i < boxes.size(); ++i) {
    const DynamicBox& b = boxes[i];
    if (t_s < b.t_in_s || t_s >= b.t_out_s) continue;
    if (b.start_move != StartMove::kNone) {
      poses.emplace_back(static_cast<int>(i), trajectory.T_w_floor(t_s) * startBoxInFloor(b, t_s));
      continue;
    }
    const double slide_in = kSlideM * (1.0 - smoothstep((t_s - b.t_in_s) / b.enter_s));
    const double slide_out = kSlideM * smoothstep((t_s - (b.t_out_s - b.enter_s)) / b.enter_s);
    const double x = t_b_c.x() + b.distance_m + 0.5 * b.size_m.x();
    const double y = b.lateral_m + b.side * slide_in + (b.crosses ? -b.side : b.side) * slide_out;
    if (b.carried) {
      const double z = -trajectory.state(0.0).T_w_b.translation().z() + 0.5 * b.size_m.z() + 0.05;
      const SE3 T_b_o(Quat::Identity(), Vec3(x, y, z));
      poses.emplace_back(static_cast<int>(i), trajectory.state(t_s).T_w_b * T_b_o);
    } else {
      const double p = b.sway_phase;
      const SE3 T_floor_o(
          so3ExpQuat(Vec3(0, 0, 0.06 * std::sin(0.5 * t_s + 3 * p))),
          Vec3(x + 0.06 * std::sin(0.9 * t_s + p), y + 0.08 * std::sin(0.6 * t_s + 2 * p), 0.5 * b.size_m.z()));
      poses.emplace_back(static_cast<int>(i), trajectory.T_w_floor(t_s) * T_floor_o);
    }
  }
  return poses;
}

}  // namespace ltlo::sim
