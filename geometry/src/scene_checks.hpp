#pragma once
// Private to evar_geometry: what load_scene checks of the vessels together, once each has
// been read: no two the same surface, none inside another, none reaching far past its
// centerline's ends (the whole tree given as one vessel).
#include "evar/geometry/scene.hpp"

namespace evar::geometry::detail {

/// base::InputError naming scene.json, the vessels and the fix.
void check_vessels_apart(const Scene& scene);

}  // namespace evar::geometry::detail
