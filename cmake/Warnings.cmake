# Project warning set, errors on project code (host and cross builds alike).
set(ATTEKF_WARNINGS
    -Wall -Wextra -Wpedantic -Wconversion -Wshadow -Wdouble-promotion
    -Wcast-qual -Wstrict-prototypes -Wmissing-prototypes -Wundef -Wvla -Werror)

# ATTEKF_WERROR OFF (the default when the project is built inside another one) keeps the
# warnings but not -Werror.
function(attekf_strict target)
  set(flags ${ATTEKF_WARNINGS})
  if(DEFINED ATTEKF_WERROR AND NOT ATTEKF_WERROR)
    list(REMOVE_ITEM flags -Werror)
  endif()
  target_compile_options(${target} PRIVATE ${flags})
endfunction()
