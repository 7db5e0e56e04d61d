#pragma once
// A simulated session written once for a test suite (`evarnode sim session`'s generator): its
// directory (removed at the end), what the generator returned, and the patient's scene as
// the node loads it. A suite holds one in a static pointer made in SetUpTestSuite.
#include <filesystem>

#include "evar/geometry/scene.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/temp_dir.hpp"

namespace evar::test {

struct SimulatedSession {
  explicit SimulatedSession(const sim::SessionPlan& plan)
      : generated(sim::generate_session(plan, dir.path / "session")),
        scene(geometry::load_scene(dir.path / "session" / generated.session.scene)) {}

  const session::Session& session() const { return generated.session; }

  TempDir dir;  // first: made before, removed after the rest
  sim::GeneratedSession generated;
  geometry::Scene scene;
};

}  // namespace evar::test
