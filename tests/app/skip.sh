# Sourced by the scripted tests: skip REASON ends the test as skipped (exit 77, ctest's
# SKIP_RETURN_CODE), or as failed under MCSLAM_STRICT_TESTS=1 (CI), where every tool the install
# script provides must be there.
skip() {
  echo "skipped: $1"
  if [ "${MCSLAM_STRICT_TESTS:-0}" = 1 ]; then echo "MCSLAM_STRICT_TESTS=1: may not skip"; exit 1; fi
  exit 77
}
