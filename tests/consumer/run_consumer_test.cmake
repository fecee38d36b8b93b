# Installs the build tree into WORK_DIR/prefix, then builds and runs the consumer.
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
  RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
if(NOT EXISTS ${WORK_DIR}/prefix/bin/mobmap)
  message(FATAL_ERROR "the mobmap executable was not installed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build
  -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=Release RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the consumer against the installed mobmap failed (${rc})")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building the consumer failed (${rc})")
endif()
# A small map from the installed tool for the consumer to open.
execute_process(COMMAND ${WORK_DIR}/prefix/bin/mobmap simulate --out ${WORK_DIR}/seq --frames 2 --noise none --quiet
  RESULT_VARIABLE rc OUTPUT_QUIET)
if(rc EQUAL 0)
  execute_process(COMMAND ${WORK_DIR}/prefix/bin/mobmap build ${WORK_DIR}/seq --out ${WORK_DIR}/map.ot --quiet
    RESULT_VARIABLE rc OUTPUT_QUIET)
endif()
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the installed mobmap could not simulate and build a map (${rc})")
endif()
execute_process(COMMAND ${WORK_DIR}/build/consumer ${WORK_DIR}/map.ot ${WORK_DIR}/seq RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the consumer ran but gave a wrong answer (${rc})")
endif()
# A consumer of the mapping component alone: configures without PCL, OpenNI2, SQLite,
# MPI or a C compiler, and answers on the same map.
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR}/../consumer_mapping -B ${WORK_DIR}/build_mapping
  -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=Release RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the mapping-only consumer failed (${rc})")
endif()
file(READ ${WORK_DIR}/build_mapping/CMakeCache.txt cache)
foreach(found IN ITEMS PCL_DIR OPENNI2 SQLITE3_ MPI_ CMAKE_C_COMPILER: GDAL_DIR mrpt)
  string(FIND "${cache}" "${found}" at)
  if(NOT at EQUAL -1)
    message(FATAL_ERROR "find_package(mobmap COMPONENTS mapping) looked for what mapping does not need: ${found} "
                        "is in ${WORK_DIR}/build_mapping/CMakeCache.txt")
  endif()
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build_mapping RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building the mapping-only consumer failed (${rc})")
endif()
execute_process(COMMAND ${WORK_DIR}/build_mapping/mapping_consumer ${WORK_DIR}/map.ot RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the mapping-only consumer ran but gave a wrong answer (${rc})")
endif()
# The installed tool reads a .pcd (through its PCD adapter, lib/mobmap/libmobmap_pcd.so).
file(WRITE ${WORK_DIR}/cloud.pcd "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
     "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n0 0 1\n0.1 0 1\n0 0.1 1\n")
execute_process(COMMAND ${WORK_DIR}/prefix/bin/mobmap analyze ${WORK_DIR}/cloud.pcd --json
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${out}${err}" "adapter" adapter_problem)
if(NOT adapter_problem EQUAL -1)
  message(FATAL_ERROR "the installed mobmap did not load its PCD adapter: ${out}${err}")
endif()
# The Python package, when it was built: importable from the installed prefix alone.
if(PYTHON)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${WORK_DIR}/prefix/lib/python3/dist-packages
    ${PYTHON} -c "import mobmap, sys; m = mobmap.open_map(sys.argv[1]); r = m.query([[1.0, 0.0, 0.01]]); sys.exit(0 if r['state'][0] == mobmap.SURFACE else 3)"
    ${WORK_DIR}/map.ot RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "import mobmap from the installed prefix failed or answered wrongly (${rc})")
  endif()
endif()
