# Per-ISA compilation of packet kernels (STYLE.md: kernel sources compile once per ISA inside
# rtc::isa_<name>; nothing outside those namespaces gets ISA flags).
#
# rtc_isa_kernels(<target> SOURCES a.cpp b.cpp) compiles every source once per ISA in RTC_ISAS
# with -DRTC_ISA_NS=isa_<name>, -DRTC_ISA_TARGET="<target list>" and -DRTC_ISA_WIDTH=<packet
# width: 4 for SSE4.2, 8 for AVX2, 16 for AVX-512>, and adds the objects to <target>. No -m flag
# reaches the compiler: the ISA applies only between RTC_ISA_BEGIN and RTC_ISA_END
# (common/simd/isa_region.h). The binary picks the best one the CPU has at run time.
set(RTC_ISAS "sse42;avx2;avx512" CACHE STRING "ISAs the packet kernels are compiled for")
set(RTC_ISA_TARGET_sse42 "sse4.2,popcnt")
set(RTC_ISA_TARGET_avx2 "avx2,fma,bmi,bmi2,popcnt")
set(RTC_ISA_TARGET_avx512 "avx512f,avx512dq,avx512bw,avx512vl,avx2,fma,bmi,bmi2,popcnt")
set(RTC_ISA_ENUM_sse42 Sse42)
set(RTC_ISA_ENUM_avx2 Avx2)
set(RTC_ISA_ENUM_avx512 Avx512)
set(RTC_ISA_WIDTH_sse42 4)
set(RTC_ISA_WIDTH_avx2 8)
set(RTC_ISA_WIDTH_avx512 16)

function(rtc_isa_kernels target)
  cmake_parse_arguments(ARG "" "" "SOURCES;LINK" ${ARGN})
  foreach(isa IN LISTS RTC_ISAS)
    set(obj ${target}_isa_${isa})
    add_library(${obj} OBJECT ${ARG_SOURCES})
    target_compile_definitions(${obj} PRIVATE RTC_ISA_NS=isa_${isa} RTC_ISA_ENUM=${RTC_ISA_ENUM_${isa}}
                               RTC_ISA_WIDTH=${RTC_ISA_WIDTH_${isa}}
                               RTC_ISA_TARGET="${RTC_ISA_TARGET_${isa}}")
    target_link_libraries(${obj} PRIVATE ${ARG_LINK})
    # Vector arguments between ISA-compiled inline functions: no ABI crosses a library boundary.
    target_compile_options(${obj} PRIVATE -Wno-psabi)
    set_target_properties(${obj} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    target_sources(${target} PRIVATE $<TARGET_OBJECTS:${obj}>)
    string(TOUPPER ${isa} isa_upper)
    target_compile_definitions(${target} PUBLIC RTC_HAVE_ISA_${isa_upper}=1)
  endforeach()
endfunction()
