# SPDX-License-Identifier: Apache-2.0
# Runs scdoc on IN and writes OUT (called by man/CMakeLists.txt at build time); fails the build with
# scdoc's message and the page's name when the source is malformed.
execute_process(COMMAND ${SCDOC} INPUT_FILE ${IN} OUTPUT_FILE ${OUT} ERROR_VARIABLE err RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  file(REMOVE ${OUT})
  message(FATAL_ERROR "scdoc failed on ${IN}: ${err}")
endif()
