#pragma once
// Scheduling of the movers of issue 32's harder worlds (private to ltlo_sim). Scene::
// scheduleOcclusions calls them in this order, after the scenario's boxes and --occlusion-at; each
// draws from its own random stream and does nothing when its option is off.
#include "ltlo/sim/scene.h"

namespace ltlo::sim {

/// Start of the scenario's first events: the first 3 s (10 % of short runs) are free of movers.
double clearTimeS(const SimOptions& options);

/// Drops the boxes (carried ones too when `carried_too`) present at some time in [t0_s, t1_s].
void dropBoxesOverlapping(Scene* scene, double t0_s, double t1_s, bool carried_too);

/// --occluded-start: a box covering 40-80 % of frame 0 that leaves by 5 s.
void addOccludedStart(const SimOptions& options, Scene* scene);
/// When the occluded start's box has gone (0 without the option).
double occludedStartEndS(const Scene& scene);
/// --three-movers: a leading box, repeated crossing boxes and a carried box from t_clear on.
void addThreeMovers(const SimOptions& options, Scene* scene);
/// --walkers N (walkers.cc).
void scheduleWalkers(const SimOptions& options, Scene* scene);
/// --door (doors.cc): the leaves and their static frames.
void scheduleDoors(const SimOptions& options, Scene* scene);
/// --plain-movers: plain colours for every mover, half of the events' boxes become panels.
void applyPlainMovers(const SimOptions& options, Scene* scene);

}  // namespace ltlo::sim
