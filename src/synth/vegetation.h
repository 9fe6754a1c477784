// Vegetation of the synthetic street (private to the synth module; see VegetationOptions).
#pragma once

#include "epiloc/synth/world.h"

namespace epiloc {

// Appends hedges and tree rows (surfaces, textures with mip levels, World::vegetation) to a built
// world, from its own random stream (options.seed), for options.vegetation.
void AddVegetation(World* world);

}  // namespace epiloc
