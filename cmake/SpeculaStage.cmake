# Stage include roots. Each engine library publishes an include root that holds only its own
# folder, so "<stage>/x.h" is reachable only through that library's target and the targets
# that link it. A stage therefore cannot include the header of a later stage, nor of any
# library it does not link: the pipeline order is kept by the compiler, not by convention
# (tests/layout checks it). The root is ${build}/include/<stage>/, holding one symbolic link
# <stage> -> engine/<stage>: headers stay beside their sources, nothing in the tree moves.
#
#   specula_stage_includes(<target> <stage> [<more public include dirs>...])
function(specula_stage_includes target stage)
  set(root ${CMAKE_BINARY_DIR}/include/${stage})
  file(MAKE_DIRECTORY ${root})
  file(CREATE_LINK ${PROJECT_SOURCE_DIR}/engine/${stage} ${root}/${stage} SYMBOLIC)
  target_include_directories(${target} PUBLIC ${root} ${ARGN})
endfunction()
