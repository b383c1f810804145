// The --temporal and --mark-cells options, written once for rtc-render and rtc-master.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "common/render/temporal.h"

namespace rtc {

inline void add_temporal_options(CLI::App& app, std::string& mode, int& cells) {
  app.add_option("--temporal", mode,
                 "temporal coherence: after the first frame trace only the tiles whose rays crossed space a moving "
                 "mesh left or entered, or that a moved light shades (same pixels): auto (on unless the camera "
                 "moves over the frames rendered; rtc-master: off for a --loop where nothing moves), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  app.add_option("--mark-cells", cells,
                 "temporal coherence: voxels along the longest axis of the region where meshes move (finer: fewer "
                 "tiles retraced, more work marking; fewer where the grid would pass 2^21 voxels)")
      ->check(CLI::Range(1, kMaxMarkCellsPerAxis))
      ->capture_default_str();
}

}  // namespace rtc
