# EMPS real-data benchmark (docs/emps.md): reproduce the published IDIM-LS
# results from the records shipped in host/hdservo/data/emps (or $HDSERVO_EMPS_DIR) and write
# build/verify/emps.json.  Fails when a number is outside the targets.
.PHONY: verify-emps
verify-emps: setup
	@mkdir -p $(B)/verify
	$(PY) -m hdservo.cli emps verify --json $(B)/verify/emps.json
