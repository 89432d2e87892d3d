#!/usr/bin/env bash
# Install exactly the Debian 12 packages vmsim's build needs (../shared/STACK.md recipe),
# with sudo when not root. Does nothing when every package is already installed.
#   scripts/install-deps.sh          install what is missing
#   scripts/install-deps.sh --check  exit 1 (and list them) when packages are missing, install nothing
#   scripts/install-deps.sh --test   also the packages only the tests use (`make test`; `make demo` needs none)
set -euo pipefail

check=0
with_tests=0
for arg in "$@"; do
  case "$arg" in
    --check) check=1 ;;
    --test) with_tests=1 ;;
    *) echo "usage: scripts/install-deps.sh [--check] [--test]" >&2; exit 2 ;;
  esac
done

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libopenvdb-dev libnanovdb-dev libboost-iostreams-dev libvtk9-dev libembree-dev libtbb-dev
  libgtest-dev libgmock-dev libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
  libzip-dev zipcmp zipmerge ziptool libpugixml-dev coinor-libclp-dev libglpk-dev
  libopenmpi-dev openmpi-bin libegl-dev fonts-dejavu-core libbenchmark-dev libfmt-dev python3-imath
  zlib1g-dev libssl-dev python3 libmatio-dev libpng-dev libdeflate-dev
  # The Python module (python/): pybind11's headers, Python's, and numpy for the arrays it hands over.
  python3-dev pybind11-dev python3-numpy
)
# For the tests only (`make test`; `make demo` installs none of it): report.html validated (html5lib in strict mode,
# tidy) and opened in headless Chromium through chromedriver (selenium), its screenshot read with PIL; Gwyddion 2.62,
# the independent reader the metrology tests hold vmsim's scan readers against (headless --convert-to-gwy); pytest for
# the Python module's tests (python/tests; matplotlib is optional: the examples write CSV without it).
test_packages=(chromium chromium-driver python3-selenium python3-html5lib python3-pil tidy gwyddion python3-pytest)
if [ "$with_tests" -eq 1 ]; then
  packages+=("${test_packages[@]}")
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
if [ "$check" -eq 1 ]; then
  echo "missing packages: ${missing[*]}" >&2
  exit 1
fi

echo "vmsim: installing ${#missing[@]} Debian package(s): ${missing[*]}" >&2
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "vmsim: not root and sudo is not available; install as root: apt-get install ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q
$sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
