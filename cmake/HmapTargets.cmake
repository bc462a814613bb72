# hmap_add_library(NAME SOURCES ... ) — one static library per folder, alias hmap::NAME,
# warnings and C++20 set on the target, headers installed under include/hmap/NAME.
function(hmap_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(hmap_${name} STATIC ${ARG_SOURCES})
  add_library(hmap::${name} ALIAS hmap_${name})
  set_target_properties(hmap_${name} PROPERTIES EXPORT_NAME ${name} OUTPUT_NAME hmap_${name})
  target_compile_features(hmap_${name} PUBLIC cxx_std_20)
  target_include_directories(hmap_${name} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/src>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(hmap_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  hmap_set_warnings(hmap_${name})
  install(TARGETS hmap_${name} EXPORT hmapTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/hmap/${name}
    FILES_MATCHING PATTERN "*.hpp")
endfunction()

function(hmap_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
    -Wno-sign-conversion)
  # A unity build includes each source into a generated unit, and GCC then takes a class deriving
  # from a type in that source's anonymous namespace for one in a header.
  if(HMAP_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wno-subobject-linkage)
  endif()
  if(HMAP_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
      -fno-sanitize-recover=undefined)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined)
  endif()
endfunction()
