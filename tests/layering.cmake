# The layer rule of lib/, stated here once and enforced by the ctest test `layering`
# (cmake -DSPX_SOURCE_DIR=<repo> -P tests/layering.cmake). docs/ARCHITECTURE.md explains it.
#
#   core <- cl <- io <- geom <- render | nn | body <- metrics | synth <- fit <- avatar <- (apps)
#
# A file of module A may include a header of module B only when B is A or B sits on a lower
# level. Modules on one level are siblings and do not include each other. Every
# `#include "..."` of lib/**/*.{c,h,cpp} is read: "<module>/<file>" is that module's private
# header, "smplpix/<name>.h" a public header owned by the module in SPX_PUBLIC below (so the
# public headers obey the rule too), a bare "<file>" a header beside the includer.
# A new module or public header must be added to these tables (an unknown one fails the test).
set(SPX_LEVELS
  core=0
  cl=1
  io=2
  geom=3
  render=4 nn=4 body=4
  metrics=5 synth=5
  fit=6
  avatar=7
  api=8) # the umbrella header smplpix/smplpix.h: for users only, no lib file includes it
set(SPX_PUBLIC
  core=core files=core comm=core
  device=cl
  mesh=io camera=io image=io depth=io npy=io npz=io safetensors=io bvh=io amass=io
  bake=geom
  render=render raster=render
  unet=nn vgg=nn patchgan=nn
  body=body
  metrics=metrics
  synth=synth
  fit=fit
  avatar=avatar
  smplpix=api)

if(NOT SPX_SOURCE_DIR)
  message(FATAL_ERROR "layering: pass -DSPX_SOURCE_DIR=<repository root>")
endif()

# KEY=VALUE items -> variables <prefix>_KEY
macro(spx_table prefix)
  foreach(kv ${ARGN})
    string(REPLACE "=" ";" kv "${kv}")
    list(GET kv 0 k)
    list(GET kv 1 v)
    set(${prefix}_${k} ${v})
  endforeach()
endmacro()
spx_table(level ${SPX_LEVELS})
spx_table(public ${SPX_PUBLIC})

# module of a repository-relative file under lib/ ("" when it has none)
function(spx_module_of rel out)
  if(rel MATCHES "^lib/include/smplpix/([A-Za-z0-9_]+)\\.h$")
    set(name ${CMAKE_MATCH_1})
    if(NOT DEFINED public_${name})
      set(${out} "?public:${name}" PARENT_SCOPE)
      return()
    endif()
    set(${out} ${public_${name}} PARENT_SCOPE)
  elseif(rel MATCHES "^lib/([A-Za-z0-9_]+)/")
    set(${out} ${CMAKE_MATCH_1} PARENT_SCOPE)
  else()
    set(${out} "" PARENT_SCOPE)
  endif()
endfunction()

file(GLOB_RECURSE files RELATIVE ${SPX_SOURCE_DIR} ${SPX_SOURCE_DIR}/lib/*.c ${SPX_SOURCE_DIR}/lib/*.h
     ${SPX_SOURCE_DIR}/lib/*.cpp)
list(SORT files)
set(bad 0)
set(checked 0)
foreach(f ${files})
  spx_module_of(${f} mod)
  if(NOT DEFINED level_${mod})
    message(SEND_ERROR "layering: ${f}: module '${mod}' has no level in tests/layering.cmake")
    math(EXPR bad "${bad} + 1")
    continue()
  endif()
  get_filename_component(dir ${f} DIRECTORY)
  file(STRINGS ${SPX_SOURCE_DIR}/${f} lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
  foreach(line ${lines})
    string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]*)\".*$" "\\1" inc "${line}")
    if(inc MATCHES "^smplpix/")
      set(target lib/include/${inc})
    elseif(inc MATCHES "/")
      set(target lib/${inc})
    else()
      set(target ${dir}/${inc})
    endif()
    if(NOT EXISTS ${SPX_SOURCE_DIR}/${target})
      message(SEND_ERROR "layering: ${f} includes \"${inc}\", which is not a file of lib/")
      math(EXPR bad "${bad} + 1")
      continue()
    endif()
    spx_module_of(${target} tmod)
    math(EXPR checked "${checked} + 1")
    if(NOT DEFINED level_${tmod})
      message(SEND_ERROR "layering: ${f} includes \"${inc}\" of module '${tmod}', which has no level in tests/layering.cmake")
      math(EXPR bad "${bad} + 1")
    elseif(NOT tmod STREQUAL mod AND NOT level_${tmod} LESS level_${mod})
      message(SEND_ERROR "layering: ${f} includes \"${inc}\": back-edge ${mod} (level ${level_${mod}}) -> ${tmod} (level ${level_${tmod}}); a module includes only its own headers and those of lower levels")
      math(EXPR bad "${bad} + 1")
    endif()
  endforeach()
endforeach()
list(LENGTH files nfiles)
if(checked LESS 100)
  message(FATAL_ERROR "layering: only ${checked} includes found under ${SPX_SOURCE_DIR}/lib: wrong source dir?")
endif()
if(bad)
  message(FATAL_ERROR "layering: ${bad} violation(s) of the layer rule in tests/layering.cmake")
endif()
message(STATUS "layering: ${nfiles} files, ${checked} includes, no back-edge")
