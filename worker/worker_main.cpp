// rtc-worker: connects to an rtc-master, receives its scene and renders the tiles it is given
// on all cores, streaming the pixels back; reconnects with back-off when the master goes away.
#include <cstdio>
#include <new>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "common/base/cli_checks.h"
#include "common/base/error.h"
#include "common/base/isa.h"
#include "common/base/log.h"
#include "common/base/process_memory.h"
#include "common/scene/scene_cli.h"
#include "protocol/auth.h"
#include "protocol/message.h"
#include "protocol/net/connection.h"
#include "worker/worker_client.h"

namespace {

int run(int argc, char** argv) {
  // Before any thread starts: a build's freed scratch stays for the next (process_memory.h).
  const rtc::FreedMemoryPolicy freed_memory = rtc::keep_freed_memory();
  CLI::App app{"rtc-worker: render tiles for an rtc-master"};
  rtc::WorkerOptions o;
  std::string token_file, isa_text, log_level = "info", kd_clip = "auto";
  app.add_option("--connect", o.connect, "the master's HOST:PORT")->capture_default_str();
  app.add_option("--threads", o.threads, "render threads (default: all cores)")->check(CLI::Range(1, 1024));
  app.add_option("--token-file", token_file, "file holding the shared token the master requires")->check(rtc::kNotEmpty);
  app.add_option("--tls-ca", o.tls_ca, "PEM certificates to trust: connect over TLS and verify the master's certificate")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-server-name", o.tls_server_name, "the name the master's certificate must carry (default: the --connect host)")->check(rtc::kNotEmpty);
  app.add_option("--isa", isa_text, "kernel ISA: sse4 (4-wide packets), avx2 (8-wide) or avx512 (16-wide); default: the best this CPU and build support")->check(rtc::kNotEmpty);
  rtc::add_kd_clip_option(app, kd_clip);
  app.add_option("--name", o.name, "name shown in the master's log (default: the host name)")->check(rtc::kNotEmpty);
  app.add_option("--retry-seconds", o.retry_seconds,
                 "give up when the master has been unreachable this long (0: retry for ever)")
      ->check(rtc::kNotNan)
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  app.add_flag("--stay", o.stay, "when the master says goodbye, wait for the next one instead of exiting");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")->capture_default_str();
  if (const std::optional<int> status = rtc::parse_command_line(app, argc, argv, "rtc-worker")) return *status;
  rtc::init_logging(log_level);
  rtc::log_freed_memory_policy(freed_memory);
  if (!isa_text.empty()) {
    try {
      o.isa = rtc::parse_isa(isa_text);
      rtc::require_cpu_support(*o.isa);
    } catch (const rtc::Error& e) {
      throw rtc::Error(std::string("--isa: ") + e.what());
    }
  }
  o.kd_clip = rtc::parse_kd_clip(kd_clip);
  if (rtc::net::parse_host_port(o.connect, "--connect").port == 0) {
    throw rtc::Error("--connect " + o.connect + ": port 0 is not a port a master listens on");
  }
  if (!o.tls_server_name.empty() && o.tls_ca.empty()) {
    throw rtc::Error("--tls-server-name " + o.tls_server_name +
                     " applies to TLS only: give --tls-ca too (the certificates to trust the master's by)");
  }
  if (o.name.size() > rtc::protocol::kMaxName) {
    throw rtc::Error("--name: " + std::to_string(o.name.size()) + " bytes, over the limit of " +
                     std::to_string(rtc::protocol::kMaxName));
  }
  if (!token_file.empty()) o.token = rtc::protocol::read_token_file_warning_if_weak(token_file);
  return rtc::run_worker(o);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rtc-worker: error: out of memory (std::bad_alloc): the process may use less memory than it needs here (ulimit -v, a container's limit)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rtc-worker: error: %s\n", e.what());
    return 1;
  }
}
