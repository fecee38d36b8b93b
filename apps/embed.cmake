# Writes the contents of IN as a C++ raw string literal into OUT.
file(READ ${IN} content)
file(WRITE ${OUT} "R\"mobmapyaml(${content})mobmapyaml\"")
