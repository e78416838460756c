// The small synthetic scene the test city's tests share.
#pragma once

#include <filesystem>

#include "core/stage.h"
#include "testcity/testcity.h"
#include "tests/test_support.h"

namespace skyfall::synth::testing_scene {

// The bound on the RPC written for each image.
inline constexpr double kRpcFitTolPx = 0.01;
// Rendering maps rays into the scene frame with an affine fit of the
// ENU -> UTM map (reported error ~5 mm at most for these scenes); at 0.5 m
// GSD that is 0.01 px, plus the RPC fit: 0.03 px leaves margin for both.
inline constexpr double kRenderVsRpcTolPx = 0.03;

inline SynthOptions SmallScene() {
  SynthOptions o;
  o.size_m = 128.0;
  o.views = 4;
  o.seed = 7;
  return o;
}

struct Scene {
  std::filesystem::path root;
  SynthResult result;
};

inline Scene MakeScene(const SynthOptions& o) {
  Scene s;
  s.root = skyfall::testing::ScratchDir("synth");
  NullProgress progress;
  s.result = RunSynth(o, s.root.string(), progress);
  return s;
}

}  // namespace skyfall::synth::testing_scene
