# Sourced by the benchmark scripts: B, the skyfall binary to measure
# (SKYFALL_BIN, else build/bin/skyfall, built when missing; copy it elsewhere
# to keep building while a benchmark runs), and RUN_ARGS, extra `skyfall run`
# arguments from SKYFALL_RUN_ARGS (e.g. "--set idu.samples=1").
if [ -z "${SKYFALL_BIN:-}" ]; then
  [ -x build/bin/skyfall ] || bash scripts/build.sh
  SKYFALL_BIN=$(pwd)/build/bin/skyfall
fi
B=$SKYFALL_BIN
read -r -a RUN_ARGS <<< "${SKYFALL_RUN_ARGS:-}"
