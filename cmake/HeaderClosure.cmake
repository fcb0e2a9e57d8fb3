# attekf_header_closure(<out-var> FILES <file...> DIRS <dir...>)
#
# Every header reachable from FILES through #include "name" lines, looked up in DIRS (the
# include path of the library), FILES themselves first if they are headers. Headers not
# found in DIRS (the C library's, a user's) are not followed. The scan ignores #if, so a
# header included only in one scalar build (ekf_fixed.h) is listed for every build: the
# set is what a copy of the library must contain to compile in any configuration.
# Used for the installed headers (firmware/CMakeLists.txt) and the file list of
# docs/porting.md (cmake/PortingDoc.cmake); works in script mode (cmake -P) too.
function(attekf_header_closure out)
  cmake_parse_arguments(A "" "" "FILES;DIRS" ${ARGN})
  set(result "")
  set(todo ${A_FILES})
  while(todo)
    list(POP_FRONT todo file)
    file(STRINGS "${file}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"[^\"]+\"")
    foreach(line IN LISTS lines)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*$" "\\1" name "${line}")
      foreach(dir IN LISTS A_DIRS)
        if(EXISTS "${dir}/${name}")
          get_filename_component(path "${dir}/${name}" ABSOLUTE)
          if(NOT path IN_LIST result)
            list(APPEND result "${path}")
            list(APPEND todo "${path}")
          endif()
          break()
        endif()
      endforeach()
    endforeach()
  endwhile()
  foreach(file IN LISTS A_FILES)
    get_filename_component(path "${file}" ABSOLUTE)
    if(path MATCHES "\\.h$" AND NOT path IN_LIST result)
      list(PREPEND result "${path}")
    endif()
  endforeach()
  list(SORT result)
  set(${out} "${result}" PARENT_SCOPE)
endfunction()
