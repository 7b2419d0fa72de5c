# Writes the manual page OUT for the command BIN with HELP2MAN: the
# command's --help and --version, then one section for each command's own
# --help, kept as printed (no-fill). Run as cmake -P.
set(include_file ${OUT}.sections)
file(WRITE ${include_file} "[DESCRIPTION]\nhaarlight relights objects under HDR environments with precomputed Haar\nwavelet transport, or, for scenes that move, with shadow maps of area lights\n(relight-dynamic); each command below lists its options.\n")
foreach(cmd precompute relight relight-dynamic view info check bench bench-dynamic bench-precompute devices)
  execute_process(COMMAND ${BIN} ${cmd} --help OUTPUT_VARIABLE text RESULT_VARIABLE rc ERROR_QUIET)
  if(NOT rc EQUAL 0)
    continue()
  endif()
  # roff: backslashes printed as such, and no line may start a request
  string(REPLACE "\\" "\\e" text "${text}")
  string(REGEX REPLACE "(^|\n)([.'])" "\\1\\\\&\\2" text "${text}")
  string(TOUPPER "${cmd}" title)
  file(APPEND ${include_file} "[COMMAND ${title}]\n.nf\n${text}.fi\n")
endforeach()
execute_process(COMMAND ${HELP2MAN} --no-info --no-discard-stderr
                        --name "all-frequency relighting of static and moving scenes"
                        --include ${include_file} --output ${OUT}.tmp ${BIN}
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "help2man failed (${rc}) on ${BIN}")
endif()
file(RENAME ${OUT}.tmp ${OUT})
