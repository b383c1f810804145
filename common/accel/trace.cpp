// Run-time dispatch of the ray-stream kernels.
#include "common/accel/trace.h"

#include <cmath>
#include <string>

#include "common/base/error.h"

namespace rtc {

#ifdef RTC_HAVE_ISA_SSE42
namespace isa_sse42 {
const TraceKernels& trace_kernels_for_isa();
}
#endif
#ifdef RTC_HAVE_ISA_AVX2
namespace isa_avx2 {
const TraceKernels& trace_kernels_for_isa();
}
#endif
#ifdef RTC_HAVE_ISA_AVX512
namespace isa_avx512 {
const TraceKernels& trace_kernels_for_isa();
}
#endif

const TraceKernels& trace_kernels(Isa isa) {
  require_cpu_support(isa);
  switch (isa) {
#ifdef RTC_HAVE_ISA_SSE42
    case Isa::Sse42:
      return isa_sse42::trace_kernels_for_isa();
#endif
#ifdef RTC_HAVE_ISA_AVX2
    case Isa::Avx2:
      return isa_avx2::trace_kernels_for_isa();
#endif
#ifdef RTC_HAVE_ISA_AVX512
    case Isa::Avx512:
      return isa_avx512::trace_kernels_for_isa();
#endif
    default:
      break;
  }
  throw_isa_not_compiled(isa);
}

const TraceKernels& trace_kernels() { return trace_kernels(best_isa()); }

float refined_distance(const glm::vec3& org, const glm::vec3& dir, const glm::vec3& a, const glm::vec3& b,
                       const glm::vec3& c, float fallback) {
  const glm::dvec3 A(a);
  const glm::dvec3 n = glm::cross(glm::dvec3(b) - A, glm::dvec3(c) - A);
  const double den = glm::dot(n, glm::dvec3(dir));
  const double t = glm::dot(n, A - glm::dvec3(org)) / den;
  return std::isfinite(t) ? static_cast<float>(t) : fallback;
}

void refine_hit_distances(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                          const RayQuery* rays, RayHit* hits, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    if (hits[i].prim == kNoHit) continue;
    const glm::uvec3 t = triangles[hits[i].prim];
    hits[i].t = refined_distance(rays[i].org, rays[i].dir, positions[t.x], positions[t.y], positions[t.z], hits[i].t);
  }
}

}  // namespace rtc
