// The --temporal and --mark-cells options, written once for rtc-render and rtc-master.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "common/render/temporal.h"

namespace rtc {

/// `has_loop`: the program has --loop (rtc-master), whose frames where nothing moves turn auto off.
inline void add_temporal_options(CLI::App& app, std::string& mode, int& cells, bool has_loop) {
  app.add_option("--temporal", mode,
                 std::string("temporal coherence: after the first frame trace only the tiles whose rays crossed space a "
                             "moving mesh left or entered, or that a moved light shades (same pixels): auto (on unless "
                             "the camera moves over the frames rendered") +
                     (has_loop ? " or a --loop's frames hold nothing that moves" : "") +
                     "), on, off; always off for a single frame")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  app.add_option("--mark-cells", cells,
                 "temporal coherence: voxels along the longest axis of the region where meshes move (finer: fewer "
                 "tiles retraced, more work marking; fewer where the grid would pass 2^21 voxels)")
      ->check(CLI::Range(1, kMaxMarkCellsPerAxis))
      ->capture_default_str();
}

}  // namespace rtc
