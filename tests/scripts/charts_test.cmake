# CTest charts_redraw (issue 12): the chart scripts draw with matplotlib from saved records. Redraws the
# culling figures from docs/culling/dag.json into a scratch directory; every figure must be written
# as an SVG, and the README tables (every number) must equal the committed ones; the same for the
# out-of-core budget figure (docs/trace/budget.json).
#   cmake -DPYTHON=<python3 with matplotlib> -DSOURCE=<source dir> -DWORK=<scratch dir> -P charts_test.cmake
file(REMOVE_RECURSE ${WORK})
execute_process(COMMAND ${PYTHON} ${SOURCE}/scripts/chart-dag --from ${SOURCE}/docs/culling/dag.json --out ${WORK}
                WORKING_DIRECTORY ${SOURCE} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "scripts/chart-dag failed (${rc}):\n${out}\n${err}")
endif()
foreach(f proxy-bytes convert gallery-bytes gallery-cull gallery-mrays forest-2k-bytes forest-2k-cull forest-2k-mrays)
  if(NOT EXISTS ${WORK}/${f}.svg)
    message(FATAL_ERROR "scripts/chart-dag wrote no ${f}.svg")
  endif()
  file(READ ${WORK}/${f}.svg head LIMIT 400)
  if(NOT head MATCHES "<svg")
    message(FATAL_ERROR "${f}.svg is not an SVG:\n${head}")
  endif()
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/README.md ${SOURCE}/docs/culling/README.md RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "the redrawn README differs from docs/culling/README.md (${WORK}/README.md)")
endif()
# The out-of-core figure (issue 9) from docs/trace/budget.json: the SVG, and budget.md equal to the committed one.
execute_process(COMMAND ${PYTHON} ${SOURCE}/scripts/chart-budget --from ${SOURCE}/docs/trace/budget.json --out ${WORK}/trace
                WORKING_DIRECTORY ${SOURCE} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "scripts/chart-budget failed (${rc}):\n${out}\n${err}")
endif()
file(READ ${WORK}/trace/budget.svg head LIMIT 400)
if(NOT head MATCHES "<svg")
  message(FATAL_ERROR "budget.svg is not an SVG:\n${head}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK}/trace/budget.md ${SOURCE}/docs/trace/budget.md RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "the redrawn budget.md differs from docs/trace/budget.md (${WORK}/trace/budget.md)")
endif()
message(STATUS "redrew 8 culling figures from docs/culling/dag.json and the budget figure from docs/trace/budget.json; tables unchanged")
file(REMOVE_RECURSE ${WORK})
