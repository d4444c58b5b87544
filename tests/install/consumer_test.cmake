# CTest install_consumer (issues 12, 54): install the reader library to a temporary prefix, build
# docs/examples/trace and docs/examples/path_trace against it with find_package(rtpack CONFIG REQUIRED),
# trace camera rays of a sample package and path-trace another out of core, and compare the hit file and
# the image byte for byte with rtpack-trace's.
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -P consumer_test.cmake
foreach(v BUILD SOURCE WORK)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "consumer_test.cmake needs -D${v}=...")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})

set(CWD ${WORK})
include(${CMAKE_CURRENT_LIST_DIR}/run.cmake)

# 1. Install only the reader component.
run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/prefix --component reader)
file(GLOB_RECURSE installed RELATIVE ${WORK}/prefix ${WORK}/prefix/*)
list(SORT installed)
message(STATUS "installed: ${installed}")
foreach(f include/rtpack/rtpack.h)
  if(NOT EXISTS ${WORK}/prefix/${f})
    message(FATAL_ERROR "the install has no ${f}")
  endif()
endforeach()
# Nothing but the public header, the library and its CMake files: no internal header leaks.
foreach(f ${installed})
  if(NOT f MATCHES "^include/rtpack/rtpack\\.h$|^lib[^/]*/librtpack\\.so|^lib[^/]*/cmake/rtpack/rtpack(Config|ConfigVersion|Targets|Targets-[a-z]+)\\.cmake$")
    message(FATAL_ERROR "unexpected file in the install: ${f}")
  endif()
endforeach()

# 2. Build the example against the prefix alone (a fresh CMake project; no path into this source tree).
run(${CMAKE_COMMAND} -S ${SOURCE}/docs/examples/trace -B ${WORK}/example -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${WORK}/prefix)
run(${CMAKE_COMMAND} --build ${WORK}/example)

# 3. Same rays, same hits: the example (through the installed library) against rtpack-trace.
run(${BUILD}/rtpack-convert ${SOURCE}/samples/generated/gallery.glb -q -o ${WORK}/gallery.rtp)
run(${BUILD}/rtpack-trace ${WORK}/gallery.rtp --make-camera-rays 160x120 --camera 0 --rays ${WORK}/cam.rays
    --hits ${WORK}/trace.hits)
# Runs the example on the camera rays (extra arguments: its PACKET), requires its output to match
# `expect` and its hit file `hits` to be rtpack-trace's byte for byte.
function(example_matches_trace hits expect)
  run(${WORK}/example/trace_rays ${WORK}/gallery.rtp ${WORK}/cam.rays ${WORK}/${hits} ${ARGN})
  message(STATUS "${RUN_OUT}")
  if(NOT RUN_OUT MATCHES "${expect}")
    message(FATAL_ERROR "the example's output does not match '${expect}': ${RUN_OUT}")
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/trace.hits ${WORK}/${hits} RESULT_VARIABLE same)
  if(NOT same EQUAL 0)
    message(FATAL_ERROR "the installed library's hits differ from rtpack-trace's (${WORK}/trace.hits vs ${hits})")
  endif()
endfunction()
example_matches_trace(example.hits "19200 rays, [1-9][0-9]* hit")
# The same rays in packets of 16 (rows of 16 camera rays): the same hits, and packets were taken.
example_matches_trace(packet.hits "[1-9][0-9]* packets of 16" 16)
# A packet size the library refuses: its usage code and message.
execute_process(COMMAND ${WORK}/example/trace_rays ${WORK}/gallery.rtp ${WORK}/cam.rays ${WORK}/bad.hits 5
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 1 OR NOT err MATCHES "TraceOptions::packet = 5")
  message(FATAL_ERROR "packet size 5 gave exit ${rc}: ${err}")
endif()
file(SIZE ${WORK}/example.hits hits_size)
if(NOT hits_size EQUAL 384000)
  message(FATAL_ERROR "example.hits has ${hits_size} bytes, expected 19200 x 20")
endif()

# 4. The out-of-core renderer (docs/examples/path_trace) built against the same prefix: a sample
# path-traced at a 10 % budget through the installed library's RayStream, the same pixels as rtpack-trace
# --path-trace in core.
run(${CMAKE_COMMAND} -S ${SOURCE}/docs/examples/path_trace -B ${WORK}/path-example -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${WORK}/prefix)
run(${CMAKE_COMMAND} --build ${WORK}/path-example)
run(${BUILD}/rtpack-convert ${SOURCE}/samples/generated/forest-small.glb -q --chunk-target 2000 -o ${WORK}/forest.rtp)
run(${WORK}/path-example/render_paths ${WORK}/forest.rtp ${WORK}/example.ppm 96x72 10% 1024)
message(STATUS "${RUN_OUT}")
if(NOT RUN_OUT MATCHES "forest\.rtp: out of core" OR NOT RUN_OUT MATCHES " [1-9][0-9]* chunks loaded")
  message(FATAL_ERROR "the example did not render out of core: ${RUN_OUT}")
endif()
run(${BUILD}/rtpack-trace ${WORK}/forest.rtp --path-trace ${WORK}/trace.ppm --size 96x72)
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/trace.ppm ${WORK}/example.ppm RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "the installed library's out-of-core image differs from rtpack-trace's in core (${WORK}/trace.ppm vs example.ppm)")
endif()
file(SIZE ${WORK}/example.ppm ppm_size)
if(NOT ppm_size EQUAL 20749)  # the 13-byte header "P6 96 72 255" (newlines between) and 96 x 72 x 3
  message(FATAL_ERROR "example.ppm has ${ppm_size} bytes, expected 13 + 96 x 72 x 3")
endif()

# 5. A damaged package: a clear message and the library's exit code, no crash.
file(WRITE ${WORK}/bad.rtp "RTPACK00 not a package")
execute_process(COMMAND ${WORK}/example/trace_rays ${WORK}/bad.rtp ${WORK}/cam.rays ${WORK}/bad.hits
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 3 OR NOT err MATCHES "bad\\.rtp: ")
  message(FATAL_ERROR "a damaged package gave exit ${rc}: ${err}")
endif()
message(STATUS "damaged package: ${err}")
file(REMOVE_RECURSE ${WORK})
