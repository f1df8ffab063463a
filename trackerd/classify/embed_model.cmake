# SPDX-License-Identifier: Apache-2.0
# Writes OUT, a C++ source holding the text of MODEL (the `gbt` classifier's built-in model) as
# string chunks of at most 16000 characters (compilers need not take longer literals), joined at
# run time. Run by CMake at build time: cmake -DMODEL=... -DOUT=... -P embed_model.cmake
file(READ "${MODEL}" text)
get_filename_component(name "${MODEL}" NAME)
string(FIND "${text}" ")fovea_model\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${MODEL} holds the embedding's delimiter")
endif()
string(LENGTH "${text}" length)
set(chunks "")
set(at 0)
while(at LESS length)
  string(SUBSTRING "${text}" ${at} 16000 piece)
  string(APPEND chunks "    R\"fovea_model(${piece})fovea_model\",\n")
  math(EXPR at "${at} + 16000")
endwhile()
file(WRITE "${OUT}.tmp" "// Generated from ${name} by embed_model.cmake: do not edit.
#include <string>
namespace fovea::trackerd::classify::builtin {
extern const char* const kModelName;
extern const std::string kModelText;
const char* const kModelName = \"${name}\";
namespace {
const char* const kChunks[] = {
${chunks}    nullptr};
std::string joined() {
  std::string s;
  for (const char* const* c = kChunks; *c != nullptr; ++c) s += *c;
  return s;
}
}  // namespace
const std::string kModelText = joined();
}  // namespace fovea::trackerd::classify::builtin
")
file(COPY_FILE "${OUT}.tmp" "${OUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUT}.tmp")
