# mobmap_configure_target(<target>): the one place that sets the language level
# and the warning set for every first-party target.
function(mobmap_configure_target target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow)
  endif()
endfunction()

# mobmap_add_module(<name> SOURCES ... DEPS ...): a library `mobmap_<name>` with
# the alias `mobmap::<name>`, public headers under <name>/include, installed and
# exported under the name `<name>` so consumers link `mobmap::<name>`: the CMake
# package's component <name>, in an export set of its own (mobmap-<name>-targets).
function(mobmap_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(mobmap_${name} ${ARG_SOURCES})
  add_library(mobmap::${name} ALIAS mobmap_${name})
  set_target_properties(mobmap_${name} PROPERTIES EXPORT_NAME ${name})
  target_include_directories(mobmap_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  # Private headers (not installed) are included by their path under src/.
  target_include_directories(mobmap_${name} PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(mobmap_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  mobmap_configure_target(mobmap_${name})
  install(TARGETS mobmap_${name} EXPORT mobmap-${name}-targets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()

# mobmap_add_plugin(<name> SOURCES ... DEPS ...): the adapter libmobmap_<name>.so, a
# module opened when first used (util/include/mobmap/util/plugin.hpp), built into
# ${MOBMAP_PLUGIN_BUILD_DIR} and installed into <prefix>/lib/mobmap.
set(MOBMAP_PLUGIN_BUILD_DIR ${CMAKE_BINARY_DIR}/lib/mobmap)
function(mobmap_add_plugin name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(mobmap_${name} MODULE ${ARG_SOURCES})
  target_link_libraries(mobmap_${name} PRIVATE ${ARG_DEPS})
  set_target_properties(mobmap_${name} PROPERTIES PREFIX "lib" LIBRARY_OUTPUT_DIRECTORY ${MOBMAP_PLUGIN_BUILD_DIR})
  mobmap_configure_target(mobmap_${name})
  install(TARGETS mobmap_${name} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/mobmap)
endfunction()
