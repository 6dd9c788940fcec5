# Runs one command and checks its exit status and output (ctest checks only one of them).
#   cmake -DCMD="prog|arg|arg" -DEXPECT_RC=N [-DEXPECT_REGEX=re] [-DWRITE_FILE=path -DWRITE_TEXT=text] -P expect.cmake
if(DEFINED WRITE_FILE)
  file(WRITE "${WRITE_FILE}" "${WRITE_TEXT}")
endif()
string(REPLACE "|" ";" cmd "${CMD}")
execute_process(COMMAND ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(NOT "${rc}" STREQUAL "${EXPECT_RC}")
  message(FATAL_ERROR "exit status ${rc}, expected ${EXPECT_RC}")
endif()
if(DEFINED EXPECT_REGEX AND NOT "${out}${err}" MATCHES "${EXPECT_REGEX}")
  message(FATAL_ERROR "output does not match '${EXPECT_REGEX}'")
endif()
