# CTest install_tools (issue 12): the installed tools work wherever they run. Installs the tools component
# to a temporary prefix; from a working directory outside the repository, rtpack-make-scene finds its
# default meshes in PREFIX/share/rtpack, and the installed convert / inspect --verify / trace run on what it
# makes. A copy of rtpack-make-scene with no data directory anywhere fails with a message naming --mesh.
#   cmake -DBUILD=<build dir> -DWORK=<scratch dir> -P tools_test.cmake
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
include(${CMAKE_CURRENT_LIST_DIR}/run.cmake)

# Outside the repository: a fresh directory under the system's temporary directory.
if(DEFINED ENV{TMPDIR})
  set(tmp $ENV{TMPDIR})
else()
  set(tmp /tmp)
endif()
string(RANDOM LENGTH 8 tag)
set(outside ${tmp}/rtpack-install-tools-${tag})
file(MAKE_DIRECTORY ${outside}/cwd)
set(CWD ${outside}/cwd)
set(ENV{RTP_DATA_DIR} "")

run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${outside}/prefix --component tools)
set(bin ${outside}/prefix/bin)
foreach(f bin/rtpack-convert bin/rtpack-make-scene bin/rtpack-inspect bin/rtpack-trace
          share/rtpack/samples/khronos/Suzanne/glTF/Suzanne.gltf share/rtpack/samples/khronos/BoomBox/glTF/BoomBox.bin)
  if(NOT EXISTS ${outside}/prefix/${f})
    message(FATAL_ERROR "the tools install has no ${f}")
  endif()
endforeach()

run(${bin}/rtpack-make-scene gallery --count 5 -o g.glb)
run(${bin}/rtpack-convert g.glb -q -o g.rtp)
run(${bin}/rtpack-inspect g.rtp --verify)
run(${bin}/rtpack-trace g.rtp --make-camera-rays 32x24 --rays c.rays --hits c.hits)
file(SIZE ${CWD}/c.hits n)
if(NOT n EQUAL 15360)
  message(FATAL_ERROR "c.hits has ${n} bytes, expected 32 x 24 x 20")
endif()

# No data directory: a bare copy of the tool outside the repository and the prefix.
file(MAKE_DIRECTORY ${outside}/bare/bin)
file(COPY ${bin}/rtpack-make-scene DESTINATION ${outside}/bare/bin)
execute_process(COMMAND ${outside}/bare/bin/rtpack-make-scene gallery -o x.glb WORKING_DIRECTORY ${CWD}
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 2 OR NOT err MATCHES "cannot find the default mesh 'samples/khronos/Suzanne/glTF/Suzanne.gltf'.*--mesh FILE.gltf")
  message(FATAL_ERROR "a bare rtpack-make-scene gave exit ${rc}: ${err}")
endif()
if(EXISTS ${CWD}/x.glb)
  message(FATAL_ERROR "a failed rtpack-make-scene left x.glb")
endif()
# ... and with RTP_DATA_DIR it finds them.
set(ENV{RTP_DATA_DIR} ${outside}/prefix/share/rtpack)
run(${outside}/bare/bin/rtpack-make-scene gallery --count 5 -o y.glb)
file(SHA256 ${CWD}/g.glb a)
file(SHA256 ${CWD}/y.glb b)
if(NOT a STREQUAL b)
  message(FATAL_ERROR "the same scene from the same meshes differs (g.glb vs y.glb)")
endif()
message(STATUS "installed tools ran from ${CWD}; a bare rtpack-make-scene said: ${err}")
file(REMOVE_RECURSE ${outside} ${WORK})
