# Warnings live in an INTERFACE target that every Specula target links privately.
add_library(specula_warnings INTERFACE)
target_compile_options(specula_warnings INTERFACE
  -Wall -Wextra -Wno-missing-field-initializers
  $<$<BOOL:${SPECULA_WERROR}>:-Werror>)
