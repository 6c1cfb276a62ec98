# The layering check (docs/architecture.md): no core source includes gRPC,
# the API protos or a client. Run at build time by the bitewise_layering
# target: cmake -DFILES_LIST=<file with one path per line> -DSTAMP=<file>
# -P check_layering.cmake. Fails naming every file, line and include.
file(STRINGS "${FILES_LIST}" files)
set(violations "")
foreach(path IN LISTS files)
  file(STRINGS "${path}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
  foreach(line IN LISTS lines)
    if(line MATCHES "[<\"](grpcpp/|grpc/|grpc\\+\\+/|bitewise/v1/|bitewise/meal/|bitewise/console/|clients/)")
      string(APPEND violations "\n  ${path}: ${line}")
    endif()
  endforeach()
endforeach()
if(violations)
  message(FATAL_ERROR "core libraries must not include gRPC, the API protos "
    "or a client (docs/architecture.md, \"Layers\"):${violations}")
endif()
if(STAMP)
  file(WRITE "${STAMP}" "")
endif()
