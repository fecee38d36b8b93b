# Writes the contents of IN as a C++ raw string literal into OUT. DELIM (default
# mobmapyaml) closes the literal and must not occur in IN.
if(NOT DEFINED DELIM)
  set(DELIM mobmapyaml)
endif()
file(READ ${IN} content)
string(FIND "${content}" ")${DELIM}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${IN} contains the delimiter )${DELIM}\"")
endif()
file(WRITE ${OUT} "R\"${DELIM}(${content})${DELIM}\"")
