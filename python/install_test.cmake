# cmake --install puts the package where python3 finds it: install into a temporary prefix and
# import walkgraph from <prefix>/${INSTALL_DIR} (lib/python3.X/dist-packages, which Debian's
# python3 searches under /usr and /usr/local), outside the build tree.
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
execute_process(
  COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${WORK_DIR}/prefix/${INSTALL_DIR}
          ${PYTHON} -c "import walkgraph, sys; w = walkgraph.read_walk(sys.argv[1]); print(walkgraph.__file__, len(w.ranges))" ${WALK}
  WORKING_DIRECTORY ${WORK_DIR}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "prefix/${INSTALL_DIR}/walkgraph/__init__.py [1-9]")
  message(FATAL_ERROR "import from the installed prefix failed (${rc}): ${out}\n${err}")
endif()
message(STATUS "${out}")
