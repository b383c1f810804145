// rtc-bench --sweep (see sweep.h).
#include "tests/bench/sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/info.h>

#include "common/base/error.h"
#include "common/base/isa.h"
#include "common/base/timer.h"
#include "common/image/image.h"
#include "common/image/pixel_format.h"
#include "common/render/renderer.h"
#include "tests/bench/bench_timing.h"
#include "tests/support/embree_oracle.h"
#include "tests/support/hit_compare.h"
#include "tests/support/reference_render.h"

namespace rtc::bench {
namespace {

constexpr int kTile = 32;                  // the master's default tile size
constexpr double kLinkBitsPerS = 100e6;    // the paper's 100 Mbit/s link

struct Variant {
  std::string group, label;
  RenderSettings settings;
  Isa isa = Isa::Sse42;
  bool packets = true;
  KdBuildOptions kd;
  WireFormat wire = WireFormat::Rgba8;  // rtc-master's default for 8-bit output
  Compression compression = kDefaultCompression;
  bool is_default = false;
};

struct Result {
  Variant v;
  double build_ms = 0, render_ms = 0, codec_ms = 0, link_ms = 0, total_ms = 0;
  std::uint64_t wire_bytes = 0;
  TileRayCounts counts;
  test::ImageError error;
  bool pareto = false;
};

std::string fmt_float(double v) { return fmt::format("{:g}", v); }

std::vector<Variant> make_variants(const Scene& scene, bool quick) {
  std::vector<Variant> out;
  Variant base;
  base.group = "default";
  base.label = "shipped default";
  base.settings = scene.settings;
  base.isa = best_isa();
  base.kd.clip = kd_clip_for(scene, KdClip::Auto);
  base.is_default = true;
  out.push_back(base);
  base.is_default = false;

  auto add = [&](const std::string& group, const std::string& label, auto&& change) {
    Variant v = base;
    v.group = group;
    v.label = label;
    change(v);
    out.push_back(v);
  };
  const std::vector<int> depths = quick ? std::vector<int>{0, 2, 64} : std::vector<int>{0, 1, 2, 3, 4, 6, 8, 12, 16, 32, 64};
  for (int d : depths) {
    if (d == base.settings.max_depth) continue;
    add("reflection depth", fmt::format("max depth {}", d), [&](Variant& v) { v.settings.max_depth = d; });
  }
  const std::vector<float> weights = quick ? std::vector<float>{0.0f, 0.1f}
                                           : std::vector<float>{0.0f, 1e-4f, 1e-3f, 3e-3f, 3e-2f, 0.1f, 0.3f, 1.0f};
  for (float w : weights) {
    if (w == base.settings.min_weight) continue;
    add("ray-weight cutoff", fmt::format("min weight {:g}", w), [&](Variant& v) { v.settings.min_weight = w; });
  }
  add("reflection depth", "max depth 64, min weight 0", [&](Variant& v) {
    v.settings.max_depth = 64;
    v.settings.min_weight = 0.0f;
  });
  add("most accurate", "max depth 64, min weight 0, float, watertight", [&](Variant& v) {
    v.settings.max_depth = 64;
    v.settings.min_weight = 0.0f;
    v.settings.intersector = Intersector::Watertight;
    v.wire = WireFormat::Float;
  });
  for (WireFormat f : {WireFormat::Rgba8, WireFormat::Half, WireFormat::Float}) {
    for (Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
      if (f == base.wire && c == base.compression) continue;
      if (quick && !((f == WireFormat::Half && c == Compression::Lz4) || (f == WireFormat::Float && c == Compression::Zstd))) continue;
      add("wire format", fmt::format("{} {}", wire_format_name(f), compression_name(c)), [&](Variant& v) {
        v.wire = f;
        v.compression = c;
      });
    }
  }
  add("triangle test", base.settings.intersector == Intersector::Wald ? "watertight test" : "Wald test",
      [&](Variant& v) {
        v.settings.intersector =
            base.settings.intersector == Intersector::Wald ? Intersector::Watertight : Intersector::Wald;
      });
  for (Isa i : compiled_isas()) {
    if (!cpu_supports(i) || i == base.isa) continue;
    add("packet width / ISA", fmt::format("{} packets", isa_name(i)), [&](Variant& v) { v.isa = i; });
  }
  add("packet width / ISA", fmt::format("{} single rays", isa_name(base.isa)), [&](Variant& v) { v.packets = false; });
  const std::vector<float> kts = quick ? std::vector<float>{1.0f} : std::vector<float>{0.5f, 1.0f, 4.0f};
  for (float kt : kts) {
    add("kd-tree build", fmt::format("K_T/K_I = {:g}/{:g}", kt, base.kd.intersection_cost),
        [&](Variant& v) { v.kd.traversal_cost = kt; });
  }
  if (!quick) {
    for (int md : {12, 20}) {
      add("kd-tree build", fmt::format("kd max depth {}", md), [&](Variant& v) { v.kd.max_depth = md; });
    }
  }
  const std::vector<int> leaves = quick ? std::vector<int>{8} : std::vector<int>{2, 4, 8, 16};
  for (int l : leaves) {
    add("kd-tree build", fmt::format("kd leaf size {}", l), [&](Variant& v) { v.kd.leaf_size = l; });
  }
  add("kd-tree build", base.kd.clip ? "kd clipping off" : "kd clipping on", [&](Variant& v) { v.kd.clip = !base.kd.clip; });
  return out;
}

/// Sends the frame through the wire format as the cluster does (tiles of kTile, encoded by a
/// worker, decoded by the master); returns the decoded frame, the bytes and the codec time.
Image through_wire(const Image& frame, WireFormat wire, Compression compression, std::uint64_t& bytes, double& ms) {
  Image out(frame.width, frame.height);
  bytes = 0;
  ms = 0;
  std::vector<std::uint8_t> buf;
  for (int y0 = 0; y0 < frame.height; y0 += kTile) {
    for (int x0 = 0; x0 < frame.width; x0 += kTile) {
      const int w = std::min(kTile, frame.width - x0), h = std::min(kTile, frame.height - y0);
      Image tile(w, h);
      for (int y = 0; y < h; ++y) std::copy_n(frame.pixel(x0, y0 + y), 4 * w, tile.pixel(0, y));
      Image decoded;
      buf.clear();
      Timer t;
      const std::size_t raw = encode_tile_pixels(tile, wire, compression, 0, buf);
      const std::string why = decode_tile_pixels(buf, static_cast<std::uint32_t>(raw), w, h, wire, compression, 0, decoded);
      ms += t.elapsed_ms();
      if (!why.empty()) throw Error("sweep: decoding our own tile failed: " + why);
      bytes += buf.size();
      out.blit(decoded, x0, y0);
    }
  }
  return out;
}

/// Prints the few pixels furthest from the reference and writes the per-pixel error (largest
/// sRGB channel difference, from image_error) as an EXR next to the CSV, so a user can see
/// where error lives.
void report_worst_pixels(const std::string& label, const Image& image, const Image& reference,
                         const std::vector<double>& per_pixel, const std::filesystem::path& dir) {
  Image map(image.width, image.height);
  std::vector<std::pair<double, int>> worst;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const int i = y * image.width + x;
      const double d = per_pixel[static_cast<std::size_t>(i)];
      float* m = map.pixel(x, y);
      m[0] = m[1] = m[2] = static_cast<float>(d);
      m[3] = 1.0f;
      worst.emplace_back(d, i);
    }
  }
  const std::size_t n = std::min<std::size_t>(5, worst.size());
  std::partial_sort(worst.begin(), worst.begin() + static_cast<std::ptrdiff_t>(n), worst.end(), std::greater<>());
  std::string file = "error_" + label + ".exr";
  std::replace_if(file.begin(), file.end(), [](char ch) { return ch == ' ' || ch == ','; }, '_');
  write_image(dir / file, map);
  std::printf("  %s: worst pixels (x, y: ours / reference, linear RGB); error map in %s\n", label.c_str(), file.c_str());
  for (std::size_t i = 0; i < n; ++i) {
    const int x = worst[i].second % image.width, y = worst[i].second / image.width;
    const float* a = image.pixel(x, y);
    const float* b = reference.pixel(x, y);
    std::printf("    %4d, %4d: %.4f %.4f %.4f / %.4f %.4f %.4f (sRGB difference %.4f)\n", x, y, a[0], a[1], a[2], b[0], b[1],
                b[2], worst[i].first);
  }
}

void mark_pareto(std::vector<Result>& results) {
  for (Result& r : results) {
    r.pareto = std::none_of(results.begin(), results.end(), [&](const Result& o) {
      return o.total_ms <= r.total_ms && o.error.rmse <= r.error.rmse &&
             (o.total_ms < r.total_ms || o.error.rmse < r.error.rmse);
    });
  }
}

/// The reference's primary visibility against Embree's on the renderer's own (float) camera
/// rays through the pixel centres.
nlohmann::json embree_cross_check(const FrameState& fs, const test::ReferenceTracer& ref) {
  const std::vector<RayQuery> rays = test::pixel_centre_rays(fs.camera_rays);
  const std::size_t pixels = rays.size();
  std::vector<RayHit> ours(pixels), theirs(pixels);
  for (std::size_t i = 0; i < pixels; ++i) {
    const test::RefHit h = ref.intersect(glm::dvec3(rays[i].org), glm::dvec3(rays[i].dir), 0.0,
                                         std::numeric_limits<double>::infinity());
    ours[i] = h.prim == kNoHit ? RayHit{rays[i].t_max, 0.0f, 0.0f, kNoHit}
                               : RayHit{static_cast<float>(h.t), static_cast<float>(h.beta), static_cast<float>(h.gamma), h.prim};
  }
  test::EmbreeScene embree(fs.geometry->positions, fs.geometry->triangles, true);
  embree.intersect(rays.data(), theirs.data(), pixels, test::EmbreeMode::Single);
  const test::HitComparison c = test::compare_hits(fs.geometry->positions, fs.geometry->triangles, rays, ours, theirs);
  return {{"rays", c.rays},
          {"hit_miss_agreement", c.hit_miss_agreement()},
          {"hit_miss_on_edge", c.hit_miss_on_edge},
          {"same_triangle", c.same_prim},
          {"ties", c.ties},
          {"edge_grazes", c.edge_grazes},
          {"unexplained", c.bad_ties + c.same_prim_t_bad + (c.hit_miss_disagree - c.hit_miss_on_edge)},
          {"summary", c.summary()}};
}

}  // namespace

int run_sweep(const Scene& scene, const SweepOptions& options) {
  std::filesystem::create_directories(options.out_dir);
  const int frame = scene.animation.frame_begin;
  const int threads = static_cast<int>(tbb::info::default_concurrency());
  std::printf("sweep: %s, %dx%d, %d spp, %d threads, %d reps; output in %s\n", scene.name.c_str(), scene.width,
              scene.height, std::max(1, scene.settings.spp), threads, options.reps, options.out_dir.string().c_str());

  // The reference: the same frame, traced in double with deep reflections and no cutoff.
  const std::shared_ptr<FrameState> fs = build_frame_state(scene, frame, scene.settings, KdBuildOptions{});
  const test::ReferenceTracer tracer(fs->geometry->positions, fs->geometry->triangles);
  test::ReferenceStats ref_stats;
  const Image reference = reference_render(*fs, tracer, test::ReferenceOptions{}, &ref_stats);
  write_image(options.out_dir / "reference.exr", reference);
  nlohmann::json ref_json = {{"scene", scene.name},
                             {"width", scene.width},
                             {"height", scene.height},
                             {"triangles", fs->geometry->triangles.size()},
                             {"bvh_build_ms", tracer.build_ms()},
                             {"render_ms", ref_stats.ms},
                             {"primary_rays", ref_stats.primary},
                             {"shadow_rays", ref_stats.shadow},
                             {"reflection_rays", ref_stats.reflection},
                             {"non_finite", test::count_non_finite(reference)}};
  std::printf("reference (double, max depth 64, no weight cutoff): %.0f ms (+ %.0f ms BVH), %llu primary, %llu shadow, "
              "%llu reflection rays\n",
              ref_stats.ms, tracer.build_ms(), static_cast<unsigned long long>(ref_stats.primary),
              static_cast<unsigned long long>(ref_stats.shadow), static_cast<unsigned long long>(ref_stats.reflection));
  if (options.embree_check) {
    ref_json["embree_visibility"] = embree_cross_check(*fs, tracer);
    std::printf("reference visibility vs Embree (robust, single rays, pixel centres): %s\n",
                ref_json["embree_visibility"]["summary"].get<std::string>().c_str());
  }
  {
    std::ofstream f(options.out_dir / "reference.json");
    f << ref_json.dump(2) << "\n";
    if (!f) throw Error((options.out_dir / "reference.json").string() + ": cannot write");
  }

  const std::vector<Variant> variants = make_variants(scene, options.quick);
  std::vector<Result> results;
  int bad_variants = ref_json["non_finite"].get<std::uint64_t>() > 0 ? 1 : 0;
  std::printf("%-20s %-30s %9s %9s %8s %9s %10s %10s %9s %8s %8s %8s\n", "group", "setting", "build ms", "render ms",
              "codec ms", "bytes", "link ms", "total ms", "RMSE", "PSNR", "max err", ">1/255");
  for (const Variant& v : variants) {
    Result r;
    r.v = v;
    Scene s = scene;
    s.settings = v.settings;
    RenderOptions ro;
    ro.isa = v.isa;
    ro.packets = v.packets;
    ro.kd = v.kd;
    ro.kd_clip = v.kd.clip ? KdClip::On : KdClip::Off;
    // Build time: a fresh renderer per rep (prepare() reuses the tree of an unchanged scene).
    std::unique_ptr<Renderer> renderer;
    std::shared_ptr<const FrameState> state;
    r.build_ms = time_median_ms(options.reps, [&] {
      state.reset();
      renderer = std::make_unique<Renderer>(s, ro);
      state = renderer->prepare(frame);
    });
    Image image;
    r.render_ms = time_median_ms(options.reps, [&] {
      r.counts = TileRayCounts{};
      image = renderer->render_frame(*state, kTile, nullptr, &r.counts);
    });
    const std::uint64_t raw_bad = test::count_non_finite(image);
    const Image received = through_wire(image, v.wire, v.compression, r.wire_bytes, r.codec_ms);
    r.link_ms = static_cast<double>(r.wire_bytes) * 8.0 / kLinkBitsPerS * 1e3;
    r.total_ms = r.build_ms + r.render_ms + r.codec_ms + r.link_ms;
    std::vector<double> per_pixel;
    r.error = test::image_error(received, reference, &per_pixel);
    if (v.is_default || v.label == "max depth 64, min weight 0") {
      report_worst_pixels(v.label, received, reference, per_pixel, options.out_dir);
    }
    r.error.non_finite += raw_bad;
    if (r.error.non_finite > 0) ++bad_variants;
    std::printf("%-20s %-30s %9.1f %9.1f %8.1f %9llu %10.1f %10.1f %9.2e %8.2f %8.4f %7.3f%%%s\n", v.group.c_str(),
                v.label.c_str(), r.build_ms, r.render_ms, r.codec_ms, static_cast<unsigned long long>(r.wire_bytes),
                r.link_ms, r.total_ms, r.error.rmse, r.error.psnr_db, r.error.max_abs, r.error.pct_over_1_255,
                r.error.non_finite > 0 ? fmt::format("  {} NaN/Inf values!", r.error.non_finite).c_str() : "");
    results.push_back(r);
  }
  mark_pareto(results);

  const std::filesystem::path csv_path = options.out_dir / "sweep.csv";
  std::ofstream csv(csv_path);
  csv << "group,setting,is_default,pareto,max_depth,min_weight,intersector,isa,packets,kd_traversal_cost,kd_intersection_cost,"
         "kd_max_depth,kd_leaf_size,kd_clip,wire,compression,build_ms,render_ms,codec_ms,wire_bytes,link_ms_100mbit,total_ms,"
         "primary_rays,shadow_rays,reflection_rays,rmse,psnr_db,max_abs,pct_over_1_255,non_finite\n";
  for (const Result& r : results) {
    const Variant& v = r.v;
    csv << '"' << v.group << "\",\"" << v.label << "\"," << (v.is_default ? 1 : 0) << ',' << (r.pareto ? 1 : 0) << ','
        << v.settings.max_depth << ',' << fmt_float(v.settings.min_weight) << ','
        << intersector_name(v.settings.intersector) << ',' << isa_name(v.isa) << ','
        << (v.packets ? 1 : 0) << ',' << fmt_float(v.kd.traversal_cost) << ',' << fmt_float(v.kd.intersection_cost) << ','
        << v.kd.max_depth << ',' << v.kd.leaf_size << ',' << (v.kd.clip ? 1 : 0) << ',' << wire_format_name(v.wire) << ','
        << compression_name(v.compression) << ',' << fmt::format("{:.3f},{:.3f},{:.3f},", r.build_ms, r.render_ms, r.codec_ms)
        << r.wire_bytes << ',' << fmt::format("{:.3f},{:.3f},", r.link_ms, r.total_ms) << r.counts.primary << ','
        << r.counts.shadow << ',' << r.counts.reflection << ','
        << fmt::format("{:.6e},{:.4f},{:.6e},{:.4f},", r.error.rmse, std::min(r.error.psnr_db, 999.0), r.error.max_abs,
                       r.error.pct_over_1_255)
        << r.error.non_finite << '\n';
  }
  csv.close();
  if (!csv) throw Error(csv_path.string() + ": cannot write");
  std::printf("wrote %s (%zu settings; Pareto front:", csv_path.string().c_str(), results.size());
  for (const Result& r : results) {
    if (r.pareto) std::printf(" [%s]", r.v.label.c_str());
  }
  std::printf(")\n");
  return bad_variants;
}

}  // namespace rtc::bench
