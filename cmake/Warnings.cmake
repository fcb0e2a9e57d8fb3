# Project warning set, errors on project code (host and cross builds alike).
set(ATTEKF_WARNINGS
    -Wall -Wextra -Wpedantic -Wconversion -Wshadow -Wdouble-promotion
    -Wcast-qual -Wstrict-prototypes -Wmissing-prototypes -Wundef -Wvla -Werror)

function(attekf_strict target)
  target_compile_options(${target} PRIVATE ${ATTEKF_WARNINGS})
endfunction()
