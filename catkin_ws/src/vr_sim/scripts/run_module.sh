#!/usr/bin/env bash
# roslaunch helper: run `python -m MODULE ARGS...` with the project's venv, dropping roslaunch's __name/__log args.
python="$1"; module="$2"; shift 2
args=()
for arg in "$@"; do
  case "$arg" in __name:=*|__log:=*) ;; *) args+=("$arg") ;; esac
done
exec "$python" -m "$module" "${args[@]}"
