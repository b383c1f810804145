# Per-ISA compilation of packet kernels (STYLE.md: kernel sources compile once per ISA inside
# rtc::isa_<name>; nothing outside those namespaces gets ISA flags).
#
# rtc_isa_kernels(<target> SOURCES a.cpp b.cpp) compiles every source once per ISA in RTC_ISAS,
# each with that ISA's flags and -DRTC_ISA_NS=isa_<name>, and adds the objects to <target>.
# Part 2 of the tracer adds avx2 and avx512 to RTC_ISAS.
set(RTC_ISAS sse42 CACHE STRING "ISAs the packet kernels are compiled for")
set(RTC_ISA_FLAGS_sse42 -msse4.2 -mpopcnt)
set(RTC_ISA_ENUM_sse42 Sse42)
set(RTC_ISA_ENUM_avx2 Avx2)
set(RTC_ISA_ENUM_avx512 Avx512)
set(RTC_ISA_FLAGS_avx2 -mavx2 -mfma -mbmi -mbmi2 -mlzcnt -mpopcnt -mf16c)
set(RTC_ISA_FLAGS_avx512 -mavx512f -mavx512dq -mavx512bw -mavx512vl -mavx2 -mfma -mbmi -mbmi2 -mlzcnt -mpopcnt -mf16c)

function(rtc_isa_kernels target)
  cmake_parse_arguments(ARG "" "" "SOURCES;LINK" ${ARGN})
  foreach(isa IN LISTS RTC_ISAS)
    set(obj ${target}_isa_${isa})
    add_library(${obj} OBJECT ${ARG_SOURCES})
    target_compile_options(${obj} PRIVATE ${RTC_ISA_FLAGS_${isa}})
    target_compile_definitions(${obj} PRIVATE RTC_ISA_NS=isa_${isa} RTC_ISA_ENUM=${RTC_ISA_ENUM_${isa}})
    target_link_libraries(${obj} PRIVATE ${ARG_LINK})
    set_target_properties(${obj} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    target_sources(${target} PRIVATE $<TARGET_OBJECTS:${obj}>)
    string(TOUPPER ${isa} isa_upper)
    target_compile_definitions(${target} PUBLIC RTC_HAVE_ISA_${isa_upper}=1)
  endforeach()
endfunction()
