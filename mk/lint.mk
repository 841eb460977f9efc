# mk/lint.mk - static analysis of firmware/ (tools/lint/lint.py): cppcheck 2.10
# with the MISRA C:2012 addon and clang-tidy.  Deviations: docs/misra-deviations.md.
#
#   make lint          core + app + canopen; counts per rule; exit 1 on any
#                      undocumented finding in LINT_STRICT (core, app)
#   make lint LINT_DIRS="firmware/core"  only some directories
# Results (every finding, counts per rule) in build/lint/lint.json; cached per
# file content in build/lint/cache.  tests/checks/70_lint.sh runs the same gate
# inside `make test`.

LINT_DIRS   ?= firmware/core firmware/app firmware/canopen
LINT_STRICT ?= firmware/core firmware/app

.PHONY: lint
lint:
	@python3 tools/lint/lint.py --strict $(LINT_STRICT) -- $(LINT_DIRS)
