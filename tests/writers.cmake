# The writers' rule of lib/, enforced by the ctest test `writers`
# (cmake -DSPX_SOURCE_DIR=<repo> -P tests/writers.cmake): every file the library writes by path
# goes through spx_atomic_open (lib/core/util.c), which checks the output policy
# (spx_file_check_writable: no device, FIFO, socket or folder replaced, no write-protected file)
# before it writes, writes a temporary that a signal handler can remove (spx_file_abort_writes),
# and checks the target again before its rename. So no other line of lib/ may open a file for
# writing, create one or rename one, except those listed below with the reason; a new writer
# that opens its own file fails this test, and tests/test_io_policy.c drives every writer of the
# table there through the hostile targets.
set(SPX_WRITER_EXCEPTIONS
  # the one implementation: the temporary's open and the rename over the target
  "lib/core/util.c:open(af->tmp_path"
  "lib/core/util.c:rename(tmp, path)"
  # OpenEXR writes by path: spx_exr_write checks the policy, hands it a temporary from
  # spx_temp_path_for (tracked for spx_file_abort_writes) and renames with spx_rename_over
  "lib/io/exr.c:exr_start_write(&e, tmp"
  # SPX_CL_DUMP_DIR: the kernel sources a developer asked to have dumped (debugging only)
  "lib/cl/program.c:fopen(path, \"wb\")")

if(NOT SPX_SOURCE_DIR)
  message(FATAL_ERROR "writers: pass -DSPX_SOURCE_DIR=<repository root>")
endif()

# a call that opens for writing, creates, renames or links a file
set(write_call "fopen[ \t]*\\([^;]*\"[wa]|[^_a-z0-9]open(at)?[ \t]*\\([^;]*O_(WRONLY|RDWR|CREAT)|[^_a-z0-9]creat[ \t]*\\(|exr_start_write|[^_a-z0-9]rename(at2?)?[ \t]*\\(|[^_a-z0-9](sym)?link[ \t]*\\(|[^_a-z0-9]mkfifo[ \t]*\\(")

file(GLOB_RECURSE files RELATIVE ${SPX_SOURCE_DIR} ${SPX_SOURCE_DIR}/lib/*.c ${SPX_SOURCE_DIR}/lib/*.cpp)
list(SORT files)
set(bad 0)
set(seen 0)
foreach(f ${files})
  file(STRINGS ${SPX_SOURCE_DIR}/${f} lines REGEX "${write_call}")
  foreach(line ${lines})
    if(line MATCHES "^[ \t]*(/?\\*|//)") # a comment
      continue()
    endif()
    math(EXPR seen "${seen} + 1")
    set(allowed 0)
    foreach(ex ${SPX_WRITER_EXCEPTIONS})
      string(FIND "${ex}" ":" colon)
      string(SUBSTRING "${ex}" 0 ${colon} exfile)
      math(EXPR from "${colon} + 1")
      string(SUBSTRING "${ex}" ${from} -1 excall)
      string(FIND "${line}" "${excall}" at)
      if(f STREQUAL exfile AND at GREATER -1)
        set(allowed 1)
      endif()
    endforeach()
    if(NOT allowed)
      string(STRIP "${line}" shown)
      message(SEND_ERROR "writers: ${f}: `${shown}` writes a file itself; use spx_atomic_open (lib/core/internal.h), "
                         "or list it in tests/writers.cmake with the reason")
      math(EXPR bad "${bad} + 1")
    endif()
  endforeach()
endforeach()
list(LENGTH files nfiles)
list(LENGTH SPX_WRITER_EXCEPTIONS nex)
if(nfiles LESS 50 OR seen LESS nex)
  message(FATAL_ERROR "writers: only ${nfiles} files and ${seen} writing calls under ${SPX_SOURCE_DIR}/lib: wrong source dir?")
endif()
if(bad)
  message(FATAL_ERROR "writers: ${bad} file write(s) outside spx_atomic_open")
endif()
message(STATUS "writers: ${nfiles} files, ${seen} writing calls, all through spx_atomic_open or listed")
