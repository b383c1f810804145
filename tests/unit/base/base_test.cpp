// common/base: error messages with places, ISA names and detection, and the progress bar's
// "draw only when asked" contract.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "common/base/error.h"
#include "common/base/frame_range.h"
#include "common/base/isa.h"
#include "common/base/log.h"
#include "common/base/progress.h"
#include "common/base/signal_name.h"

namespace rtc {
namespace {

// Everything written to `file` so far.
std::string read_all(std::FILE* file) {
  std::fflush(file);
  std::rewind(file);
  std::string out;
  char buffer[256];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) out.append(buffer, n);
  std::fseek(file, 0, SEEK_END);  // later writes append
  return out;
}

// A tmpfile() closed on scope exit.
class TempFile {
 public:
  TempFile() : file_(std::tmpfile()) {}
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    if (file_ != nullptr) std::fclose(file_);
  }
  [[nodiscard]] std::FILE* get() const { return file_; }

 private:
  std::FILE* file_;
};

// Longer than ProgressBar's redraw interval (100 ms), so the next add() may draw.
void wait_past_redraw_interval() { std::this_thread::sleep_for(std::chrono::milliseconds(150)); }

TEST(Error, IsARuntimeErrorWithTheMessage) {
  const Error e("scene.json: unknown field \"x\"");
  const std::runtime_error& base = e;
  EXPECT_STREQ(base.what(), "scene.json: unknown field \"x\"");
}

TEST(Error, AtLocationNamesFileAndLine) {
  EXPECT_EQ(at_location("bunny.obj", 812, "vertex index 5000 out of range"),
            "bunny.obj:812: vertex index 5000 out of range");
  EXPECT_EQ(at_location("a/b c.ply", 1, "x"), "a/b c.ply:1: x");
  EXPECT_EQ(at_location("big.obj", 18446744073709551615ull, "m"), "big.obj:18446744073709551615: m");
}

TEST(Error, AtLocationLeavesOutLineZero) {
  EXPECT_EQ(at_location("scene.json", 0, "unknown field \"camera.fov\""),
            "scene.json: unknown field \"camera.fov\"");
  EXPECT_EQ(at_location("", 0, ""), ": ");
}

TEST(Error, ThrowAtThrowsErrorWithTheLocation) {
  try {
    throw_at("mesh.ply", 42, "truncated file");
    FAIL() << "throw_at returned";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "mesh.ply:42: truncated file");
  }
  EXPECT_THROW(throw_at("f", 0, "m"), Error);
  try {
    throw_at("view.json", 0, "JSON parse error");
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "view.json: JSON parse error");
  }
}

TEST(Error, CheckPassesWhenTrue) {
  int evaluated = 0;
  RTC_CHECK(++evaluated == 1, "condition is evaluated exactly once");
  EXPECT_EQ(evaluated, 1);
}

TEST(ErrorDeathTest, CheckAbortsWithExpressionAndMessage) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const int lanes = 3;
  EXPECT_DEATH(RTC_CHECK(lanes == 4, "packet width"), "internal check failed at .*base_test.cpp:[0-9]+: "
                                                      "packet width \\(lanes == 4\\)");
}

TEST(Isa, NamesRoundTrip) {
  for (const Isa isa : {Isa::Sse42, Isa::Avx2, Isa::Avx512}) {
    EXPECT_EQ(parse_isa(isa_name(isa)), isa) << isa_name(isa);
  }
  EXPECT_EQ(isa_name(Isa::Sse42), "sse4.2");
  EXPECT_EQ(isa_name(Isa::Avx2), "avx2");
  EXPECT_EQ(isa_name(Isa::Avx512), "avx512");
}

TEST(Isa, ParsesEverySpelling) {
  EXPECT_EQ(parse_isa("sse4"), Isa::Sse42);
  EXPECT_EQ(parse_isa("sse42"), Isa::Sse42);
  EXPECT_EQ(parse_isa("sse4.2"), Isa::Sse42);
  EXPECT_EQ(parse_isa("avx2"), Isa::Avx2);
  EXPECT_EQ(parse_isa("avx512"), Isa::Avx512);
}

TEST(Isa, RejectsUnknownNamesWithTheName) {
  for (const char* bad : {"avx9", "", "AVX2", "sse", "avx2 ", "neon"}) {
    try {
      (void)parse_isa(bad);
      ADD_FAILURE() << "parse_isa(\"" << bad << "\") did not throw";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("\"" + std::string(bad) + "\""), std::string::npos) << message;
      EXPECT_NE(message.find("unknown ISA"), std::string::npos) << message;
      EXPECT_NE(message.find("sse4, avx2 or avx512"), std::string::npos) << message;
    }
  }
}

TEST(Isa, CompiledIsasAreSortedAndIncludeSse42) {
  const std::vector<Isa> isas = compiled_isas();
  ASSERT_FALSE(isas.empty());
  EXPECT_EQ(isas.front(), Isa::Sse42);
  EXPECT_TRUE(std::is_sorted(isas.begin(), isas.end()));
  EXPECT_EQ(std::adjacent_find(isas.begin(), isas.end()), isas.end());
}

TEST(Isa, BestIsaIsCompiledAndSupported) {
  const Isa best = best_isa();
  const std::vector<Isa> isas = compiled_isas();
  EXPECT_NE(std::find(isas.begin(), isas.end(), best), isas.end()) << isa_name(best);
  EXPECT_TRUE(cpu_supports(best)) << isa_name(best);
  // Nothing better is both compiled in and supported.
  for (const Isa isa : isas) {
    if (static_cast<int>(isa) > static_cast<int>(best)) {
      EXPECT_FALSE(cpu_supports(isa)) << isa_name(isa);
    }
  }
}

TEST(Isa, CpuSupportIsMonotonic) {
  // A CPU with AVX-512 (F, DQ, BW, VL) has AVX2 and FMA, and one with AVX2 has SSE4.2.
  if (cpu_supports(Isa::Avx512)) {
    EXPECT_TRUE(cpu_supports(Isa::Avx2));
  }
  if (cpu_supports(Isa::Avx2)) {
    EXPECT_TRUE(cpu_supports(Isa::Sse42));
  }
}

// What the kernels need of the CPU, read independently of cpu_supports (which asks CPUID through
// GCC's builtins): the kernel's own flags in /proc/cpuinfo. Every cross-ISA test skips the ISAs
// cpu_supports denies, so a wrong answer there would let them compare SSE4.2 with itself.
TEST(Isa, CpuSupportsWhatProcCpuinfoLists) {
  std::ifstream in("/proc/cpuinfo");
  if (!in) GTEST_SKIP() << "no /proc/cpuinfo";
  std::set<std::string> flags;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("flags", 0) != 0) continue;
    std::istringstream words(line.substr(line.find(':') + 1));
    for (std::string w; words >> w;) flags.insert(w);
    break;  // the first processor's
  }
  ASSERT_FALSE(flags.empty()) << "/proc/cpuinfo has no flags line";
  const auto all = [&](std::initializer_list<const char*> names) {
    return std::all_of(names.begin(), names.end(), [&](const char* n) { return flags.count(n) == 1; });
  };
  const bool sse42 = all({"sse4_2", "popcnt"});
  const bool avx2 = sse42 && all({"avx2", "fma", "bmi1", "bmi2"});
  const bool avx512 = avx2 && all({"avx512f", "avx512dq", "avx512bw", "avx512vl"});
  EXPECT_EQ(cpu_supports(Isa::Sse42), sse42);
  EXPECT_EQ(cpu_supports(Isa::Avx2), avx2);
  EXPECT_EQ(cpu_supports(Isa::Avx512), avx512);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(FrameRange, ParsesARangeOrOneFrame) {
  const FrameRange r = parse_frame_range("3-17");
  EXPECT_EQ(r.first, 3);
  EXPECT_EQ(r.last, 17);
  const FrameRange one = parse_frame_range("5");
  EXPECT_EQ(one.first, 5);
  EXPECT_EQ(one.last, 5);
}

TEST(FrameRange, RefusesBadTextWithTheReason) {
  EXPECT_EQ(error_of([] { (void)parse_frame_range(""); }), "--frames: expected A-B or A, got \"\"");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("1-x"); }), "--frames: expected A-B or A, got \"1-x\"");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("5-2"); }), "--frames: 5-2 is an empty range");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("0-99999999999999"); }),
            "--frames: 0-99999999999999: frame numbers must be at most 1000000000");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("2147483647"); }),
            "--frames: 2147483647: frame numbers must be at most 1000000000");
  EXPECT_EQ(parse_frame_range("1000000000").last, 1000000000);
  // White space anywhere is refused (std::stoi took it in front); a negative end is named as such.
  EXPECT_EQ(error_of([] { (void)parse_frame_range(" 1"); }), "--frames: expected A-B or A, got \" 1\"");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("1- 2"); }), "--frames: expected A-B or A, got \"1- 2\"");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("0--1"); }), "--frames: 0--1: frame numbers must be >= 0");
  EXPECT_EQ(error_of([] { (void)parse_frame_range("-3"); }), "--frames: -3: frame numbers must be >= 0");
}

TEST(Logging, UnknownLevelIsAnError) {
  // spdlog reads an unknown word as "off": a typo silenced the whole log.
  EXPECT_EQ(error_of([] { init_logging("Info"); }),
            "--log-level: expected trace, debug, info, warn, error, critical or off, got \"Info\"");
  EXPECT_EQ(error_of([] { init_logging("loud"); }),
            "--log-level: expected trace, debug, info, warn, error, critical or off, got \"loud\"");
}

TEST(Logging, PrintableEscapesWhatCouldForgeALine) {
  EXPECT_EQ(rtc::printable("worker-1"), "worker-1");
  EXPECT_EQ(rtc::printable("a\nb\r\tc"), "a\\nb\\r\\tc");
  EXPECT_EQ(rtc::printable(std::string("\x1b[31mred\0", 9)), "\\x1b[31mred\\x00");
  EXPECT_EQ(rtc::printable("\x7f"), "\\x7f");
  EXPECT_EQ(rtc::printable("caf\xc3\xa9 C:\\x"), "caf\xc3\xa9 C:\\x") << "UTF-8 and backslashes are kept";
  EXPECT_EQ(rtc::printable(""), "");
}

TEST(ProgressBar, CountsWithoutDrawingWhenNotForced) {
  TempFile out;
  ASSERT_NE(out.get(), nullptr);
  {
    ProgressBar bar(10, "frame 0", "px", out.get(), false);
    EXPECT_FALSE(bar.drawing());
    bar.add(3);
    wait_past_redraw_interval();
    bar.add();
    bar.add(20);
    EXPECT_EQ(bar.done(), 24u);
    EXPECT_EQ(bar.total(), 10u);
    bar.finish();
  }
  EXPECT_EQ(read_all(out.get()), "");
}

TEST(ProgressBar, NullStreamNeverDraws) {
  ProgressBar bar(5, "x", "", nullptr, true);
  EXPECT_FALSE(bar.drawing());
  wait_past_redraw_interval();
  bar.add(5);
  EXPECT_EQ(bar.done(), 5u);
}

TEST(ProgressBar, DefaultConstructorDrawsNothingWhenStderrIsNotATerminal) {
  // ctest runs tests with stderr on a pipe or file; on a terminal there is nothing to check.
  if (::isatty(::fileno(stderr)) != 0) GTEST_SKIP() << "stderr is a terminal";
  ProgressBar bar(100, "frame 0", "px");
  EXPECT_FALSE(bar.drawing());
  wait_past_redraw_interval();
  bar.add(50);
  EXPECT_EQ(bar.done(), 50u);
}

TEST(ProgressBar, ForcedDrawsLabelPercentRateAndClearsOnFinish) {
  TempFile out;
  ASSERT_NE(out.get(), nullptr);
  ProgressBar bar(200, "frame 7", "tiles", out.get(), true);
  EXPECT_TRUE(bar.drawing());
  bar.add(10);
  if (bar.elapsed_s() < 0.09) {
    EXPECT_EQ(read_all(out.get()), "") << "drawn before the first interval";
  }
  wait_past_redraw_interval();
  bar.add(40);
  const std::string drawn = read_all(out.get());
  ASSERT_FALSE(drawn.empty());
  EXPECT_EQ(drawn.front(), '\r') << drawn;
  EXPECT_NE(drawn.find("frame 7 "), std::string::npos) << drawn;
  EXPECT_NE(drawn.find(" 25.0%"), std::string::npos) << drawn;
  EXPECT_NE(drawn.find(" tiles/s"), std::string::npos) << drawn;
  EXPECT_NE(drawn.find("ETA "), std::string::npos) << drawn;
  EXPECT_NE(drawn.find('['), std::string::npos) << drawn;
  EXPECT_EQ(drawn.find('\n'), std::string::npos) << "a progress bar stays on one line: " << drawn;
  const std::string erase_line = "\x1b[K";
  EXPECT_EQ(drawn.substr(drawn.size() - erase_line.size()), erase_line);

  bar.finish();
  const std::string finished = read_all(out.get());
  EXPECT_EQ(finished, drawn + "\r" + erase_line) << "finish() clears the line";
  bar.finish();
  wait_past_redraw_interval();
  bar.add(150);
  EXPECT_EQ(read_all(out.get()), finished) << "nothing is drawn after finish()";
  EXPECT_EQ(bar.done(), 200u);
}

TEST(ProgressBar, ForcedStopsAtOneHundredPercent) {
  TempFile out;
  ASSERT_NE(out.get(), nullptr);
  ProgressBar bar(4, "", "", out.get(), true);
  wait_past_redraw_interval();
  bar.add(9);
  const std::string drawn = read_all(out.get());
  EXPECT_NE(drawn.find("100.0%"), std::string::npos) << drawn;
  EXPECT_NE(drawn.find("ETA 0:00"), std::string::npos) << drawn;
  EXPECT_NE(drawn.find("/s"), std::string::npos) << drawn;
  EXPECT_EQ(drawn.find(" /s"), std::string::npos) << "no unit gives \"1234/s\": " << drawn;
}

TEST(ProgressBar, FinishWithoutDrawingWritesNothing) {
  TempFile out;
  ASSERT_NE(out.get(), nullptr);
  {
    ProgressBar bar(10, "frame", "px", out.get(), true);
    bar.add(10);
    // Too soon to draw (unless this machine stalled for the whole interval).
    if (bar.elapsed_s() >= 0.09) GTEST_SKIP() << "the first add() came too late to test this";
  }  // the destructor finishes: no line was drawn, so none is cleared
  EXPECT_EQ(read_all(out.get()), "");
}

TEST(ProgressBar, ConcurrentAddsAreAllCounted) {
  TempFile out;
  ASSERT_NE(out.get(), nullptr);
  ProgressBar bar(40000, "threads", "rays", out.get(), true);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&bar] {
      for (int i = 0; i < 10000; ++i) bar.add();
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(bar.done(), 40000u);
  bar.finish();
}

TEST(SignalName, NamesTheStopSignalsAndNumbersTheRest) {
  EXPECT_EQ(signal_name(SIGINT), "SIGINT");
  EXPECT_EQ(signal_name(SIGTERM), "SIGTERM");
  EXPECT_EQ(signal_name(SIGHUP), "SIGHUP");
  EXPECT_EQ(signal_name(SIGKILL), "SIGKILL");
  EXPECT_EQ(signal_name(0), "signal 0");
  EXPECT_EQ(signal_name(1000), "signal 1000");
}

}  // namespace
}  // namespace rtc
