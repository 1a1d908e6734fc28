# Writes OUT, a C++ file defining kFieldViewHtml and kFieldViewJs from
# tools/field_view/index.html and viewer.js (`theia field view` writes them out).
file(READ ${DIR}/index.html html)
file(READ ${DIR}/viewer.js js)
file(WRITE ${OUT}.tmp "// Generated from tools/field_view/ by embed.cmake.\nnamespace theia {\n"
  "extern const char* const kFieldViewHtml;\nextern const char* const kFieldViewJs;\n"
  "const char* const kFieldViewHtml = R\"theia_page(${html})theia_page\";\n"
  "const char* const kFieldViewJs = R\"theia_page(${js})theia_page\";\n}\n")
file(RENAME ${OUT}.tmp ${OUT})
