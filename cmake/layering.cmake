# The layering, enforced by the build (docs/architecture.md): every source
# and header under services/ is core, except services/common/ (the server
# framework), the mains and the files of the adapter targets below. Core
# files must not include gRPC, the API protos or a client; the check runs
# before the service binaries build and fails the build naming the file and
# the include. A new file is core unless its target is an adapter.
set(BITEWISE_ADAPTER_TARGETS bitewise_bandit_service bitewise_perception_service
  bitewise_haptic_service bitewise_robot_service bitewise_camera_service
  bitewise_camera_proto)
file(GLOB_RECURSE layering_files CONFIGURE_DEPENDS
  ${PROJECT_SOURCE_DIR}/services/*.h ${PROJECT_SOURCE_DIR}/services/*.cc)
list(FILTER layering_files EXCLUDE REGEX "/services/common/|/main\\.cc$")
foreach(target IN LISTS BITEWISE_ADAPTER_TARGETS)
  get_target_property(sources ${target} SOURCES)
  get_target_property(dir ${target} SOURCE_DIR)
  foreach(source IN LISTS sources)
    get_filename_component(path ${source} ABSOLUTE BASE_DIR ${dir})
    string(REGEX REPLACE "\\.cc$" ".h" header ${path})
    list(REMOVE_ITEM layering_files ${path} ${header})
  endforeach()
endforeach()
string(REPLACE ";" "\n" layering_text "${layering_files}")
file(WRITE ${CMAKE_BINARY_DIR}/layering_files.txt "${layering_text}\n")
add_custom_command(
  OUTPUT ${CMAKE_BINARY_DIR}/layering.stamp
  COMMAND ${CMAKE_COMMAND} -DFILES_LIST=${CMAKE_BINARY_DIR}/layering_files.txt
          -DSTAMP=${CMAKE_BINARY_DIR}/layering.stamp
          -P ${PROJECT_SOURCE_DIR}/cmake/check_layering.cmake
  DEPENDS ${layering_files} ${CMAKE_BINARY_DIR}/layering_files.txt
          ${PROJECT_SOURCE_DIR}/cmake/check_layering.cmake
  COMMENT "Checking that core files include no gRPC, API protos or clients")
add_custom_target(bitewise_layering ALL DEPENDS ${CMAKE_BINARY_DIR}/layering.stamp)
foreach(binary bitewise-bandit bitewise-perception bitewise-haptic bitewise-robot
               bitewise-camera)
  if(TARGET ${binary})
    add_dependencies(${binary} bitewise_layering)
  endif()
endforeach()
