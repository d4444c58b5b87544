# CTest install_consumer (issue 12): install the reader library to a temporary prefix, build
# docs/examples/trace against it with find_package(rtpack CONFIG REQUIRED), trace camera rays of a sample
# package with it and compare the hit file byte for byte with rtpack-trace's.
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
run(${WORK}/example/trace_rays ${WORK}/gallery.rtp ${WORK}/cam.rays ${WORK}/example.hits)
message(STATUS "${RUN_OUT}")
if(NOT RUN_OUT MATCHES "19200 rays, [1-9][0-9]* hit")
  message(FATAL_ERROR "the example did not report 19200 rays with hits: ${RUN_OUT}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/trace.hits ${WORK}/example.hits RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "the installed library's hits differ from rtpack-trace's (${WORK}/trace.hits vs example.hits)")
endif()
file(SIZE ${WORK}/example.hits hits_size)
if(NOT hits_size EQUAL 384000)
  message(FATAL_ERROR "example.hits has ${hits_size} bytes, expected 19200 x 20")
endif()

# 4. A damaged package: a clear message and the library's exit code, no crash.
file(WRITE ${WORK}/bad.rtp "RTPACK00 not a package")
execute_process(COMMAND ${WORK}/example/trace_rays ${WORK}/bad.rtp ${WORK}/cam.rays ${WORK}/bad.hits
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 3 OR NOT err MATCHES "bad\\.rtp: ")
  message(FATAL_ERROR "a damaged package gave exit ${rc}: ${err}")
endif()
message(STATUS "damaged package: ${err}")
file(REMOVE_RECURSE ${WORK})
