# Per-ISA compilation of packet kernels (STYLE.md: kernel sources compile once per ISA inside
# rtc::isa_<name>; nothing outside those namespaces gets ISA flags).
#
# rtc_isa_kernels(<target> SOURCES a.cpp b.cpp) compiles every source once per ISA in RTC_ISAS
# with -DRTC_ISA_NS=isa_<name> and -DRTC_ISA_TARGET="<target list>", and adds the objects to
# <target>. No -m flag reaches the compiler: the ISA applies only between RTC_ISA_BEGIN and
# RTC_ISA_END (common/simd/isa_region.h). Part 2 of the tracer adds avx2 and avx512.
set(RTC_ISAS sse42 CACHE STRING "ISAs the packet kernels are compiled for")
set(RTC_ISA_TARGET_sse42 "sse4.2,popcnt")
set(RTC_ISA_TARGET_avx2 "avx2,fma,bmi,bmi2,lzcnt,popcnt,f16c")
set(RTC_ISA_TARGET_avx512 "avx512f,avx512dq,avx512bw,avx512vl,avx2,fma,bmi,bmi2,lzcnt,popcnt,f16c")
set(RTC_ISA_ENUM_sse42 Sse42)
set(RTC_ISA_ENUM_avx2 Avx2)
set(RTC_ISA_ENUM_avx512 Avx512)

function(rtc_isa_kernels target)
  cmake_parse_arguments(ARG "" "" "SOURCES;LINK" ${ARGN})
  foreach(isa IN LISTS RTC_ISAS)
    set(obj ${target}_isa_${isa})
    add_library(${obj} OBJECT ${ARG_SOURCES})
    target_compile_definitions(${obj} PRIVATE RTC_ISA_NS=isa_${isa} RTC_ISA_ENUM=${RTC_ISA_ENUM_${isa}}
                               RTC_ISA_TARGET="${RTC_ISA_TARGET_${isa}}")
    target_link_libraries(${obj} PRIVATE ${ARG_LINK})
    set_target_properties(${obj} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    target_sources(${target} PRIVATE $<TARGET_OBJECTS:${obj}>)
    string(TOUPPER ${isa} isa_upper)
    target_compile_definitions(${target} PUBLIC RTC_HAVE_ISA_${isa_upper}=1)
  endforeach()
endfunction()
