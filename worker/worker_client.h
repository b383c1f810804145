// rtc-worker's client: connects to a master (retrying with back-off), authenticates, receives
// the scene (or reuses it by hash), renders the tiles it is given on all its threads and
// streams the pixels back.
#pragma once

#include <optional>
#include <string>

#include "common/accel/kd_tree.h"
#include "common/base/isa.h"

namespace rtc {

struct WorkerOptions {
  std::string connect = "127.0.0.1:7878";  ///< the master's HOST:PORT
  std::string token;                       ///< empty: none (the master must not require one)
  /// TLS: PEM certificates to trust (a CA, or the master's self-signed certificate); the
  /// master's certificate must be signed by one of them and name the --connect host (or
  /// tls_server_name). Empty: plain TCP.
  std::string tls_ca;
  std::string tls_server_name;  ///< the name the master's certificate must carry; empty: the --connect host
  int threads = 0;                         ///< render threads; 0: all cores
  std::optional<Isa> isa;                  ///< empty: the best this CPU supports
  KdClip kd_clip = KdClip::Auto;           ///< kd-tree perfect splits (KdBuildOptions::clip)
  std::string name;                        ///< shown in the master's log; default: host name
  double retry_seconds = 60;  ///< give up after the master was unreachable this long (0: never)
  bool stay = false;          ///< on the master's Goodbye, wait for the next master instead of exiting
};

/// Runs until the master says goodbye (0), SIGINT/SIGTERM (0), the master stays unreachable for
/// retry_seconds or rejects the token (1, with a clear message in the log). Never throws for
/// anything a master sends.
int run_worker(const WorkerOptions& options);

}  // namespace rtc
