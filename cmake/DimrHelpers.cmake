# Helpers shared by the top-level CMakeLists.txt.

# dimr_add_layer(<layer> [PUBLIC libs...] [PRIVATE libs...])
# Creates the shared library dimr_<layer> from src/<layer>/*.cpp when that folder has
# sources (a layer appears as soon as it gets real code).
function(dimr_add_layer layer)
  cmake_parse_arguments(ARG "" "" "PUBLIC;PRIVATE" ${ARGN})
  file(GLOB_RECURSE srcs CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/src/${layer}/*.cpp)
  if(NOT srcs)
    return()
  endif()
  add_library(dimr_${layer} SHARED ${srcs})
  target_include_directories(dimr_${layer} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:include>)
  target_compile_options(dimr_${layer} PRIVATE ${DIMR_WARN_FLAGS})
  target_link_libraries(dimr_${layer} PUBLIC ${ARG_PUBLIC} PRIVATE ${ARG_PRIVATE})
  if(DIMR_HAVE_ROS)
    set_target_properties(dimr_${layer} PROPERTIES
      LIBRARY_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_LIB_DESTINATION})
  endif()
endfunction()

# dimr_add_layer_tests(<layer>)
# One gtest executable test_<layer> from test/<layer>/*.cpp, linked to dimr_<layer>.
# With catkin it goes through catkin_add_gtest (built by the `tests` target, run by ctest);
# without catkin it is a plain gtest executable registered with add_test.
function(dimr_add_layer_tests layer)
  if(NOT TARGET dimr_${layer})
    return()
  endif()
  file(GLOB srcs CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/test/${layer}/*.cpp)
  if(NOT srcs)
    return()
  endif()
  set(name test_${layer})
  if(DIMR_HAVE_ROS)
    if(NOT CATKIN_ENABLE_TESTING)
      return()
    endif()
    catkin_add_gtest(${name} ${srcs} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} TIMEOUT 600)
    if(NOT TARGET ${name})
      return()
    endif()
  else()
    find_package(GTest REQUIRED)
    add_executable(${name} ${srcs})
    target_link_libraries(${name} GTest::gtest_main GTest::gtest)
    add_test(NAME ${name} COMMAND ${name} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
    if(NOT TARGET tests)
      add_custom_target(tests)
    endif()
    add_dependencies(tests ${name})
  endif()
  target_compile_options(${name} PRIVATE ${DIMR_WARN_FLAGS})
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/test)
  target_compile_definitions(${name} PRIVATE
    DIMR_SOURCE_DIR="${PROJECT_SOURCE_DIR}" DIMR_BINARY_DIR="${CMAKE_BINARY_DIR}")
  target_link_libraries(${name} dimr_${layer})
  if(TARGET dimr_cli)
    add_dependencies(${name} dimr_cli)
    target_compile_definitions(${name} PRIVATE DIMR_CLI="$<TARGET_FILE:dimr_cli>")
  endif()
endfunction()
