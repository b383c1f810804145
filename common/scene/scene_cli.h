// Command-line options shared by the programs that load a scene (rtc-render, rtc-master): the
// scene file and the settings that override it, registered and applied the same way in both so
// the same flags give the same pixels. Header-only; include it from mains only (needs CLI11).
#pragma once

#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "common/base/cli_checks.h"
#include "common/base/log.h"
#include "common/base/timer.h"
#include "common/scene/load.h"

namespace rtc {

struct SceneCliOptions {
  std::string scene_path;  ///< empty: the built-in default scene
  int width = 0, height = 0, spp = 0, max_depth = -1;
  float min_weight = -1.0f;
  std::string intersector;  ///< empty: the scene's
};

/// How messages name the scene: its file, or "(built-in default)" for an empty path.
inline std::string scene_label(const std::string& scene_path) {
  return scene_path.empty() ? std::string("(built-in default)") : scene_path;
}
inline std::string scene_label(const SceneCliOptions& o) { return scene_label(o.scene_path); }

/// Registers SCENE and --width --height --spp --max-depth --min-weight --intersector on `app`.
inline void add_scene_cli_options(CLI::App& app, SceneCliOptions& o) {
  app.add_option("scene", o.scene_path,
                 "scene file (.json scene or view.json, .obj, .ply, .gltf/.glb, .nff) or a folder holding "
                 "view.json; "
                 "omitted: the built-in default scene");
  app.add_option("--width", o.width, "image width (default: the scene's)")->check(CLI::Range(1, 32768));
  app.add_option("--height", o.height, "image height (default: the scene's)")->check(CLI::Range(1, 32768));
  app.add_option("--spp", o.spp, "samples per pixel (default: the scene's, normally 1)")->check(CLI::Range(1, 4096));
  app.add_option("--max-depth", o.max_depth, "reflection bounces (default: the scene's, normally 8)")
      ->check(CLI::Range(0, 64));
  app.add_option("--min-weight", o.min_weight, "ray-weight cutoff for reflections (default: the scene's, normally 0.001)")
      ->check(kNotNan)
      ->check(CLI::Range(0.0f, 1.0f));
  app.add_option("--intersector", o.intersector,
                 "ray/triangle test: wald (fast) or watertight (no rays through shared edges) "
                 "(default: the scene's, normally wald)")
      ->check(CLI::IsMember({"wald", "watertight"}));
}

/// Registers --kd-clip auto|on|off (rtc-render, rtc-worker, rtc-bench) into `text`, checked;
/// rtc::parse_kd_clip() turns it into the KdClip the renderer takes.
inline void add_kd_clip_option(CLI::App& app, std::string& text) {
  app.add_option("--kd-clip", text,
                 "kd-tree perfect splits (straddling triangles clipped to each node: faster tracing, "
                 "1-5x slower builds): auto (on for the trees built once: the static meshes' and each moving "
                 "mesh's object-space tree; off for world-space trees rebuilt as a mesh moves, rtc-render's "
                 "--rebuild-moving-trees), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
}

/// Loads the scene (or the built-in one), applies the overrides and logs what was loaded.
/// Throws rtc::Error naming the file for a bad scene.
inline Scene load_scene_from_cli(const SceneCliOptions& o) {
  Timer load_timer;
  if (!o.scene_path.empty()) spdlog::info("loading scene {}", o.scene_path);  // a large one takes seconds
  Scene scene = o.scene_path.empty() ? default_scene() : load_scene(o.scene_path);
  if (o.width > 0 || o.height > 0) {
    set_resolution(scene, o.width > 0 ? o.width : scene.width, o.height > 0 ? o.height : scene.height);
  }
  if (o.spp > 0) scene.settings.spp = o.spp;
  if (o.max_depth >= 0) scene.settings.max_depth = o.max_depth;
  if (o.min_weight >= 0.0f) scene.settings.min_weight = o.min_weight;
  if (!o.intersector.empty()) {
    scene.settings.intersector = o.intersector == "watertight" ? Intersector::Watertight : Intersector::Wald;
  }
  spdlog::info("scene {}: {}, {}, {}, {}x{}, loaded in {:.0f} ms", scene_label(o),
               counted(scene.meshes.size(), "mesh", "meshes"), counted(scene.triangle_count(), "triangle", "triangles"),
               counted(scene.lights.size(), "light", "lights"), scene.width, scene.height, load_timer.elapsed_ms());
  return scene;
}

/// Checks the camera of every frame in [first, last] (rtc::check_cameras: throws rtc::Error
/// naming the scene) and warns when some of them lie outside the scene's animation.
inline void check_frames_to_render(const Scene& scene, int first, int last, const SceneCliOptions& o) {
  check_cameras(scene, first, last, scene_label(o));
  if (const std::string note = frames_outside_animation_note(scene, first, last); !note.empty()) {
    spdlog::warn("scene {}: {}", scene_label(o), note);
  }
}

}  // namespace rtc
