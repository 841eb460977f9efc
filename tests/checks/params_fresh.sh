#!/usr/bin/env bash
# Fails if the files generated from firmware/params/params.toml are stale:
# regenerate into a temp dir and diff against the committed ones.
cd "$(dirname "$0")/../.." || exit 1
PY=.venv/bin/python; [ -x "$PY" ] || PY=python3
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
if ! "$PY" tools/gen_params.py --out-dir "$tmp" 2>"$tmp/err"; then
    echo "not ok - gen_params.py failed: $(head -1 "$tmp/err")"; exit 0
fi
for f in firmware/app/hd_param_table.h firmware/app/hd_param_table.c host/hdservo/params_gen.py docs/parameters.md; do
    if diff -q "$tmp/$f" "$f" >/dev/null 2>&1; then
        echo "ok - generated $f is fresh"
    else
        echo "not ok - generated $f is stale (run tools/gen_params.py)"
    fi
done
# the firmware facts the host reads (loop rate, Q formats, signal / fault / mode enums, EMCY codes)
if ! "$PY" tools/gen_fw_const.py --out-dir "$tmp" 2>"$tmp/err2"; then
    echo "not ok - gen_fw_const.py failed: $(head -1 "$tmp/err2")"
elif diff -q "$tmp/host/hdservo/fw_const.py" host/hdservo/fw_const.py >/dev/null 2>&1; then
    echo "ok - generated host/hdservo/fw_const.py is fresh"
else
    echo "not ok - generated host/hdservo/fw_const.py is stale (run tools/gen_fw_const.py)"
fi
