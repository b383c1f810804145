// rtc-master's server: accepts workers over TCP, authenticates them, sends them the scene,
// hands out tiles from the TileQueue, reassembles and writes frames, logs frame rates next to
// the link-bound frame rate. One Asio thread owns all state; frames are written on another.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/image/image.h"
#include "common/image/pixel_format.h"
#include "common/render/temporal.h"
#include "common/scene/scene.h"

namespace rtc {

struct MasterOptions {
  std::string listen = "127.0.0.1:7878";  ///< HOST:PORT; port 0 picks a free one
  std::string token;                      ///< empty: no authentication (loopback only)
  /// TLS for every connection (OpenSSL through Asio): the master's certificate chain and private
  /// key, PEM files; both empty: plain TCP.
  std::string tls_cert, tls_key;
  int tile_size = 32;
  WireFormat wire = WireFormat::Rgba8;
  Compression compression = kDefaultCompression;
  std::uint8_t channels = 0;  ///< kChannelDepth / kChannelNormal carried for EXR output
  double link_mbps = 0;       ///< 0: measure on the first worker's connection
  int min_workers = 1;        ///< no frame starts before this many workers are ready
  /// > 0: give up (exit 1) when fewer than min_workers are ready this many seconds after
  /// listening, or none for this long while frames are open during the run; 0: wait for ever.
  double wait_seconds = 0;
  int frames_in_flight = 2;
  int tiles_per_worker = 0;   ///< K; 0: 2 x the worker's threads + 2 (at least 2)
  int first_frame = 0, last_frame = 0;  ///< inclusive
  double loop_seconds = 0;  ///< > 0: cycle through the frames until this much time has passed
  std::string out_pattern;  ///< empty: frames are discarded
  bool multiple_frames = false;  ///< for expand_frame_pattern
  ImageWriteOptions write_options;
  std::string stats_json;   ///< JSON lines file, empty: none
  std::string ready_file;   ///< gets "HOST:PORT\n" once listening (for scripts with port 0); removed when listening stops
  int heartbeat_ms = 1000;           ///< at most heartbeat_timeout_ms / 3 (the master lowers it)
  int heartbeat_timeout_ms = 10000;  ///< silence after which a worker is dropped
  int auth_timeout_ms = 10000;       ///< time a new connection has to authenticate
  /// Connections one peer address may hold open at once, authenticated or not (64 local workers
  /// on one host fit; a runaway script does not exhaust the master's file descriptors).
  int max_connections_per_host = 256;
  /// Of those, connections that have not authenticated yet: a host cannot park many idle
  /// handshakes (each for up to auth_timeout_ms) to keep its real workers out. 64 lets a host
  /// start 64 workers at once without one being turned away.
  int max_unauthenticated_per_host = 64;
  int drain_seconds = 30;            ///< after SIGINT/SIGTERM: time to finish frames in flight
  std::uint32_t probe_bytes = 4u << 20;  ///< link measurement size (0.34 s at 100 Mbit/s)
  /// Object-space temporal coherence: after a frame, hand out only the tiles whose rays
  /// crossed space that a moving mesh left or entered (or that a moved light shades), keep the
  /// other tiles' pixels (common/render/temporal.h). Decided by rtc-master's main
  /// (choose_temporal over the frames and --temporal), which also sizes the tiles by it.
  TemporalChoice temporal;
  int mark_cells = kDefaultMarkCells;  ///< mark grid cells along its longest axis
};

/// Runs until every frame is written (exit 0), a signal stops it (after the frames in flight
/// finish or are abandoned and the finished ones are written: exit 128 + the signal's number
/// when the run was cut short, else 0), or a fatal error (listen failure, unwritable output:
/// throws rtc::Error). Returns the process exit code.
int run_master(const Scene& scene, const MasterOptions& options);

/// What of --listen can be checked before the scene loads: it resolves, it is a loopback
/// address unless a token is given, and its port (unless 0) can be bound now. Throws rtc::Error
/// ("--listen HOST:PORT: <reason>").
void check_listen(const MasterOptions& options);

}  // namespace rtc
