# Shell helpers sourced by the setup scripts (not run on their own).

# ensure_apt WHY PKG...: install the Debian packages that are missing (sudo when not root).
ensure_apt() {
  local why=$1; shift
  local need=() pkg
  for pkg in "$@"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
  done
  if [ ${#need[@]} -gt 0 ]; then
    echo "setup: installing ${need[*]} ($why)"
    local sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq && $sudo apt-get install -y -qq "${need[@]}" >/dev/null
  fi
}

# python311 WHAT: print a Python 3.11 interpreter ($PYTHON, python3.11 or python3), or fail.
python311() {
  local what=$1 py=${PYTHON:-python3.11}
  command -v "$py" >/dev/null 2>&1 || py=python3
  "$py" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || {
    echo "setup: $what needs Python 3.11, found $("$py" --version 2>&1)" >&2; return 1; }
  echo "$py"
}

# ensure_free_disk MIB WHAT: fail with one line when the project's disk has less than MIB free
# (pip otherwise stops half-way through the venv with "[Errno 28] No space left on device").
ensure_free_disk() {
  local need=$1 what=$2 free
  free=$(df -Pm . | awk 'NR == 2 {print $4}')
  if [ "$free" -lt "$need" ]; then
    echo "setup: error: $what needs about $need MiB free on $(df -P . | awk 'NR == 2 {print $6}'), found $free MiB" >&2
    return 1
  fi
}
