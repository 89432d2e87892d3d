# vmsim_module(NAME DEPENDS <targets...>)
# One static library per module, built from the module folder's *.cpp (headers sit beside them).
# A module without sources yet is an INTERFACE library, so later modules can already name it.
function(vmsim_module name)
  cmake_parse_arguments(ARG "" "" "DEPENDS;PRIVATE_DEPENDS" ${ARGN})
  file(GLOB _srcs CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/*.cpp")
  set(_target vmsim_${name})
  if(_srcs)
    add_library(${_target} STATIC ${_srcs})
    target_include_directories(${_target} PUBLIC "${CMAKE_SOURCE_DIR}")
    target_link_libraries(${_target} PUBLIC ${ARG_DEPENDS} PRIVATE ${ARG_PRIVATE_DEPENDS})
    set_target_properties(${_target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  else()
    add_library(${_target} INTERFACE)
    target_include_directories(${_target} INTERFACE "${CMAKE_SOURCE_DIR}")
    target_link_libraries(${_target} INTERFACE ${ARG_DEPENDS})
  endif()
  add_library(vmsim::${name} ALIAS ${_target})
endfunction()

# vmsim_test_suite(NAME DEPENDS <targets...>)
# One GoogleTest executable per module folder of tests/ (tests/<name>/*_test.cpp).
function(vmsim_test_suite name)
  cmake_parse_arguments(ARG "" "" "DEPENDS" ${ARGN})
  file(GLOB _srcs CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/${name}/*_test.cpp")
  if(NOT _srcs)
    return()
  endif()
  set(_target ${name}_tests)
  add_executable(${_target} ${_srcs})
  target_link_libraries(${_target} PRIVATE ${ARG_DEPENDS} GTest::gtest GTest::gtest_main)
  # The test code itself at -O1: it compiles ~1.5x faster than at -O3 (make test's build is mostly tests) and runs the
  # libraries under test, which keep the build's optimisation. No fast-math anywhere, so results are the same.
  target_compile_options(${_target} PRIVATE -O1)
  # Test files compile in batches too (issue 20: make test's build is half tests); their file-local helpers carry
  # distinct names so that no batch sees a clash (-DVMSIM_TEST_UNITY_BATCH=0 compiles each suite as one file: the check).
  set_target_properties(${_target} PROPERTIES UNITY_BUILD_BATCH_SIZE ${VMSIM_TEST_UNITY_BATCH})
  target_compile_definitions(${_target} PRIVATE
    VMSIM_SOURCE_DIR="${CMAKE_SOURCE_DIR}" VMSIM_SHARED_DIR="${VMSIM_SHARED_DIR}"
    VMSIM_BINARY_DIR="${CMAKE_BINARY_DIR}")
  gtest_discover_tests(${_target} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS ${name})
endfunction()
