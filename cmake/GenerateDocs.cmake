# Writes the man page and the bash completion of the `mmval` command from its
# own --help output, so that both follow the command line without a second
# description of it (help2man is not among the project's packages; this needs
# nothing but CMake). Run at build time (target mmval_docs):
#   cmake -DMMVAL=<built mmval> -DMAN=<out/mmval.1> -DCOMPLETION=<out/mmval> -DVERSION=<x.y.z> -P GenerateDocs.cmake

function(mmval_help out_var)
  execute_process(COMMAND "${MMVAL}" ${ARGN} --help OUTPUT_VARIABLE text RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "mmval ${ARGN} --help failed (${rc}): ${err}")
  endif()
  set(${out_var} "${text}" PARENT_SCOPE)
endfunction()

# Names listed in a help text's section (`Subcommands:` or `Options:`): the
# first word of each entry line (two spaces, then the name).
function(mmval_section_names text section out_var)
  string(REPLACE ";" "\\;" text "${text}")
  string(REPLACE "\n" ";" lines "${text}")
  set(inside OFF)
  set(names "")
  foreach(line IN LISTS lines)
    if(line MATCHES "^[A-Za-z].*:$")
      if(line STREQUAL "${section}:")
        set(inside ON)
      else()
        set(inside OFF)
      endif()
    elseif(inside AND line MATCHES "^  ([^ ]+)")
      set(first "${CMAKE_MATCH_1}")
      if(section STREQUAL "Options")
        # "-h,--help" -> -h --help; "--out TEXT" was cut at the space already.
        string(REPLACE "," ";" parts "${first}")
        foreach(p IN LISTS parts)
          if(p MATCHES "^-")
            list(APPEND names "${p}")
          endif()
        endforeach()
      else()
        list(APPEND names "${first}")
      endif()
    endif()
  endforeach()
  set(${out_var} "${names}" PARENT_SCOPE)
endfunction()

# Help text as a preformatted roff block: backslashes escaped, and lines that
# start with '.' or '\'' protected.
function(mmval_roff text out_var)
  string(REPLACE "\\" "\\e" text "${text}")
  string(REGEX REPLACE "(^|\n)([.'])" "\\1\\\\&\\2" text "${text}")
  set(${out_var} ".nf\n${text}\n.fi\n" PARENT_SCOPE)
endfunction()

mmval_help(top)
mmval_section_names("${top}" "Subcommands" subs)
if(NOT subs)
  message(FATAL_ERROR "no subcommands found in `mmval --help`")
endif()

mmval_roff("${top}" top_roff)
set(man ".\\\" Generated from `mmval --help` by cmake/GenerateDocs.cmake; do not edit.
.TH MMVAL 1 \"\" \"mmval ${VERSION}\" \"User Commands\"
.SH NAME
mmval \\- validate pore-scale simulations of fine-particle migration against micromodel experiments
.SH SYNOPSIS
.B mmval
.I SUBCOMMAND
[\\fIOPTIONS\\fR]
.SH DESCRIPTION
${top_roff}.SH SUBCOMMANDS
")

set(cases "")
set(top_words "${subs};-h;--help;--version")
list(JOIN top_words " " top_words)
foreach(sub IN LISTS subs)
  mmval_help(help ${sub})
  mmval_roff("${help}" roff)
  string(APPEND man ".SS mmval ${sub}\n${roff}")
  mmval_section_names("${help}" "Options" opts)
  mmval_section_names("${help}" "Subcommands" nested)
  foreach(n IN LISTS nested)
    mmval_help(nested_help ${sub} ${n})
    mmval_roff("${nested_help}" nested_roff)
    string(APPEND man ".SS mmval ${sub} ${n}\n${nested_roff}")
    mmval_section_names("${nested_help}" "Options" nested_opts)
    list(JOIN nested_opts " " nested_words)
    string(APPEND cases "    \"${sub} ${n}\") words=\"${nested_words}\" ;;\n")
  endforeach()
  set(words ${nested} ${opts})
  list(JOIN words " " words)
  string(APPEND cases "    \"${sub}\") words=\"${words}\" ;;\n")
endforeach()

string(APPEND man ".SH ENVIRONMENT
.TP
.B MMVAL_DATA_DIR
Folder holding reference\\-data/ and cases/; without it mmval looks in ../share/mmval beside its executable, then in the source tree of a build\\-tree binary.
.SH FILES
.TP
.I <prefix>/share/mmval/reference\\-data
Literature and experiment values with their sources.
.TP
.I <prefix>/share/mmval/cases
Example case files (those whose data outside the repository this build did not find are not installed; see NOT-INSTALLED.txt there).
.TP
.I <prefix>/share/mmval/shared\\-data
Shared data sets that installed cases read (e.g. the Pore2Chip mask), each with its PROVENANCE.md and licence.
")
file(WRITE "${MAN}" "${man}")

# Case kinds, for `mmval init <TAB>` and `mmval case-doc <TAB>`.
execute_process(COMMAND "${MMVAL}" case-doc OUTPUT_VARIABLE doc RESULT_VARIABLE rc)
string(REGEX MATCHALL "\n## kind `[^`]+`" kind_lines "${doc}")
set(kinds "")
foreach(k IN LISTS kind_lines)
  string(REGEX REPLACE ".*`([^`]+)`" "\\1" k "${k}")
  list(APPEND kinds "${k}")
endforeach()
list(JOIN kinds " " kinds)

file(WRITE "${COMPLETION}" "# bash completion for mmval. Generated from `mmval --help` by cmake/GenerateDocs.cmake; do not edit.
_mmval() {
  local cur=\"\${COMP_WORDS[COMP_CWORD]}\" key=\"\" words=\"\"
  if (( COMP_CWORD == 1 )); then
    COMPREPLY=( $(compgen -W \"${top_words}\" -- \"\${cur}\") )
    return
  fi
  key=\"\${COMP_WORDS[1]}\"
  if [[ \${key} == peer ]] && (( COMP_CWORD >= 3 )); then key=\"peer \${COMP_WORDS[2]}\"; fi
  case \"\${key}\" in
${cases}  esac
  if [[ \${cur} != -* && ( \${key} == init || \${key} == case-doc ) ]] && (( COMP_CWORD == 2 )); then
    words=\"${kinds}\"
  fi
  COMPREPLY=( $(compgen -W \"\${words}\" -- \"\${cur}\") )
  if [[ \${cur} != -* ]]; then COMPREPLY+=( $(compgen -f -- \"\${cur}\") ); fi
}
complete -o filenames -F _mmval mmval
")
