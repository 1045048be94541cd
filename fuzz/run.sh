#!/usr/bin/env bash
# Runs fuzz targets one after another at the lowest priority, from a snapshot of the built
# binaries, in libFuzzer fork mode so one crash does not end the run (artifacts/<target>/).
# Usage: fuzz/run.sh SECONDS TARGET...
# Installs cargo-fuzz from crates.io when it is missing and builds the targets (stable
# toolchain with RUSTC_BOOTSTRAP=1, no sanitizer, debug assertions) before running them.
# Logs: fuzz/logs/<target>.log; new corpus entries: fuzz/corpus/<target>/.
set -u
cd "$(dirname "$0")"
secs=$1; shift
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked || { echo "run.sh: cannot install cargo-fuzz"; exit 1; }
fi
RUSTC_BOOTSTRAP=1 cargo fuzz build -s none -a || { echo "run.sh: the targets do not build"; exit 1; }
snap=$(mktemp -d /tmp/relief-fuzzbin.XXXXXX)
for t in "$@"; do cp "target/x86_64-unknown-linux-gnu/release/$t" "$snap/"; done
mkdir -p logs
for t in "$@"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  extra=()
  [ "$t" = hgt ] && extra=(-max_len=2884802)
  [ "$t" = cli_args ] && extra=(-dict=cli_args.dict)
  start=$(date +%s)
  nice -n 19 "$snap/$t" "corpus/$t" "seeds/$t" -fork=1 -ignore_crashes=1 -ignore_ooms=1 \
    -ignore_timeouts=1 -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=2048 -artifact_prefix="artifacts/$t/" -print_final_stats=1 "${extra[@]}" \
    > "logs/$t.log" 2>&1
  rc=$?
  echo "$t: $(( $(date +%s) - start )) s, exit $rc" >> logs/summary.txt
done
rm -rf "$snap"
