# GLSL -> SPIR-V at build time, embedded as a C header in the build tree:
#   shaders/<stage>/<name>.comp  ->  ${build}/spirv/<stage>/<name>.comp.h
#   defining   static const uint32_t <stage>_<name>_comp[] = {...};
# The runtime never opens a .spv file. --depfile makes edits to included
# headers (shaders/shared/*.h) trigger a rebuild.
find_program(GLSLANG_VALIDATOR glslangValidator REQUIRED)
set(SPECULA_SHADER_ROOT ${CMAKE_CURRENT_LIST_DIR}/../shaders)
get_filename_component(SPECULA_SHADER_ROOT ${SPECULA_SHADER_ROOT} ABSOLUTE)
set(SPECULA_SPIRV_DIR ${CMAKE_BINARY_DIR}/spirv)

# specula_add_shaders(<target> <stage/name.ext>...) adds the headers to an INTERFACE target.
function(specula_add_shaders target)
  set(headers)
  foreach(src IN LISTS ARGN)
    set(hdr ${SPECULA_SPIRV_DIR}/${src}.h)
    string(REGEX REPLACE "[/.]" "_" var ${src})
    get_filename_component(hdr_dir ${hdr} DIRECTORY)
    add_custom_command(OUTPUT ${hdr}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${hdr_dir}
      COMMAND ${GLSLANG_VALIDATOR} --quiet --target-env vulkan1.2 -I${SPECULA_SHADER_ROOT}
              --vn ${var} --depfile ${hdr}.d -o ${hdr} ${SPECULA_SHADER_ROOT}/${src}
      DEPENDS ${SPECULA_SHADER_ROOT}/${src}
      DEPFILE ${hdr}.d
      COMMENT "glslang ${src}"
      VERBATIM)
    list(APPEND headers ${hdr})
  endforeach()
  add_custom_target(${target}_spirv DEPENDS ${headers})
  add_library(${target} INTERFACE)
  add_dependencies(${target} ${target}_spirv)
  target_include_directories(${target} INTERFACE ${SPECULA_SPIRV_DIR} ${SPECULA_SHADER_ROOT})
endfunction()
