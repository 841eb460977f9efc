# Compensators (issue 5): a small shared library for the Python double-precision
# reference tests (ctypes).  It links the optimised firmware objects
# (build/opt/libhdfw.a, -O2 -fPIC) behind a thin batch-call shim that is NOT
# firmware (tests/python/ffi/comp_ffi.c).  Only the objects the shim needs are
# pulled from the archive.
COMP_SO := $(B)/lib/libhdcomp.so

$(COMP_SO): tests/python/ffi/comp_ffi.c $(B)/opt/libhdfw.a
	@mkdir -p $(@D)
	$(HOST_CC) -std=c99 -Wall -Wextra -Werror -O2 -fPIC -shared $(FW_INC) -o $@ $< $(B)/opt/libhdfw.a

.PHONY: comp-so
comp-so: $(COMP_SO)

BUILD_TESTS_EXTRA += $(COMP_SO)
