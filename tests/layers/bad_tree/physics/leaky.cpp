// A fixture for the layer check, never compiled: an engine file that reaches up a layer,
// into a library the engine must not use, and out of its folder. The check must refuse it.
#include "scene/scene.hpp"
#include <nlohmann/json.hpp>
#include "../server/room.hpp"
#include "no_such_neighbour.hpp"
