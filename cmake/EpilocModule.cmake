# epiloc_module(NAME SOURCES ... [PUBLIC_LINK ...] [PRIVATE_LINK ...])
# Declares the library target epiloc_<NAME> of one module: src/<NAME>/*.cc with public headers in
# include/epiloc/<NAME>/.
function(epiloc_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_LINK;PRIVATE_LINK" ${ARGN})
  add_library(epiloc_${name} STATIC ${ARG_SOURCES})
  add_library(epiloc::${name} ALIAS epiloc_${name})
  target_include_directories(epiloc_${name} PUBLIC $<BUILD_INTERFACE:${EPILOC_SOURCE_DIR}/include>
                                                   $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(epiloc_${name} PUBLIC ${ARG_PUBLIC_LINK} PRIVATE ${ARG_PRIVATE_LINK})
  # Installed as epiloc::<name> (epilocConfig.cmake); static, so other projects link it whole.
  set_target_properties(epiloc_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON EXPORT_NAME ${name})
  install(TARGETS epiloc_${name} EXPORT epilocTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
endfunction()

# epiloc_test(MODULE NAME [LINK ...]): tests/<MODULE>/<NAME>_test.cc as one GoogleTest binary,
# registered with CTest test by test.
function(epiloc_test module name)
  cmake_parse_arguments(ARG "" "" "LINK" ${ARGN})
  set(target ${module}_${name}_test)
  add_executable(${target} ${name}_test.cc)
  target_link_libraries(${target} PRIVATE epiloc_${module} ${ARG_LINK} GTest::gtest GTest::gmock GTest::gtest_main)
  target_include_directories(${target} PRIVATE ${EPILOC_SOURCE_DIR}/tests)
  target_compile_definitions(${target} PRIVATE
    EPILOC_SHARED_DATA_DIR="${EPILOC_SOURCE_DIR}/../shared/data"
    EPILOC_TEST_DATA_DIR="${EPILOC_SOURCE_DIR}/data"
    EPILOC_SOURCE_DIR="${EPILOC_SOURCE_DIR}")
  gtest_discover_tests(${target} TEST_PREFIX "${module}_" DISCOVERY_TIMEOUT 60 PROPERTIES LABELS ${module})
endfunction()
