// A scene as bytes, for the master to send to workers: everything that changes a pixel
// (meshes, materials, lights, camera, resolution, settings, animation) in a versioned,
// little-endian format written out in protocol/protocol.md ("Scene bytes").
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace rtc {

/// Deterministic: the same scene gives the same bytes (so their SHA-256 names the scene).
[[nodiscard]] std::vector<std::uint8_t> serialize_scene(const Scene& scene);

/// The inverse: a scene that renders bit-identically to the one serialized. The bytes are
/// untrusted: throws rtc::Error("<what>: <reason>") for truncation, bad counts, indices out of
/// range, non-finite values, unknown format version; never allocates more than the bytes can
/// hold, never crashes.
[[nodiscard]] Scene deserialize_scene(std::span<const std::uint8_t> bytes, const std::string& what);

}  // namespace rtc
