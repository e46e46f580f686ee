#!/bin/bash
# run.sh WHERE FILE [FUNC...]: each test function in its own process (timeout 600 s, 8 GB address space), junit XML
# per function in results/WHERE/. WHERE=284 runs HEAD's test file copied here against /tmp/wt284 (alias284 maps the
# module paths); WHERE=head runs it in /work/wt/harden.
where=$1; file=$2; shift 2
mkdir -p /tmp/audit284/results/$where
funcs="$@"
[ -z "$funcs" ] && funcs=$(grep -oE "^def (test_[a-z0-9_]+)" /tmp/audit284/$file | cut -c5-)
for f in $funcs; do
  out=/tmp/audit284/results/$where/$f.xml
  [ -s "$out" ] && continue
  if [ "$where" = 284 ]; then
    (cd /tmp/audit284 && ulimit -v 8000000 && PYTHONPATH=/tmp/alias284:/tmp/wt284 timeout 600 nice -n 5 \
      /work/venvs/harden/bin/python -m pytest -q -p no:cacheprovider --rootdir /tmp/audit284 "$file::$f" \
      --junitxml=$out > /tmp/audit284/results/$where/$f.log 2>&1; echo "$f rc=$?")
  else
    (cd /work/wt/harden && ulimit -v 8000000 && timeout 600 nice -n 5 /work/venvs/harden/bin/python -m pytest -q \
      -p no:cacheprovider "tests/$file::$f" --junitxml=$out > /tmp/audit284/results/$where/$f.log 2>&1; echo "$f rc=$?")
  fi
done
