# SPDX-License-Identifier: GPL-3.0-or-later
add_compile_definitions(_DEFAULT_SOURCE)
set(RPIV_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes
    -Wmissing-prototypes -Wformat=2 -Wundef -Wvla -Wdouble-promotion)
if(RPIV_SANITIZE)
  add_compile_options(-fsanitize=${RPIV_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${RPIV_SANITIZE})
endif()
function(rpiv_warnings target)
  target_compile_options(${target} PRIVATE ${RPIV_WARNINGS})
  if(RPIV_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
