#pragma once
// Scheduling of the movers of issue 32's harder worlds (private to ltlo_sim). Scene::
// scheduleOcclusions calls them in this order, after the scenario's boxes and --occlusion-at; each
// draws from its own random stream and does nothing when its option is off.
#include "ltlo/sim/scene.h"

namespace ltlo::sim {

/// Start of the scenario's first events: the first 3 s (10 % of short runs) are free of movers.
double clearTimeS(const SimOptions& options);

/// --plain-movers: plain colours for every mover, half of the events' boxes become panels.
void applyPlainMovers(const SimOptions& options, Scene* scene);

}  // namespace ltlo::sim
