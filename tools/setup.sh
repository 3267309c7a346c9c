#!/usr/bin/env bash
# Brings a Debian 12 machine to a working Caretaker checkout: Debian packages, .venv with the
# pinned Python dependencies, the ROS 2 interface packages (rosidl), the Java plugins, the Node
# test clients and the web view's 3D bundle. Idempotent: each step records a hash of its inputs
# in .venv/.stamps and is skipped while they are unchanged, so a second run takes seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
STAMPS=$VENV/.stamps
PYTHON=${PYTHON:-python3}

log() { printf '[setup] %s (%d s)\n' "$*" "$SECONDS"; }

# hash_of FILE_OR_DIR...: one hash over the contents of every file under the arguments.
hash_of() {
  find "$@" -type f -not -path '*/target/*' -not -path '*/node_modules/*' -print0 \
    | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1
}

# step NAME HASH: true when step NAME must run (its stamp differs from HASH).
step_needed() { [ "$(cat "$STAMPS/$1" 2>/dev/null)" != "$2" ]; }
step_done() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

# 1. Debian packages: Maven and the Java libraries it builds against offline, Chromium for
#    browser tests, the compilers rosidl needs, PostgreSQL (the tests start their own server
#    with its initdb/pg_ctl; the package's own cluster is not used).
APT_PACKAGES=(
  maven junit5 libsurefire-java libmaven-compiler-plugin-java libmaven-jar-plugin-java
  libmaven-resources-plugin-java libmaven-clean-plugin-java libmaven-install-plugin-java
  libgoogle-gson-java libyaml-snake-java
  cmake g++ make ccache chromium postgresql
)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  log "installing Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# 2. The virtual environment with pinned Python dependencies.
# One without pip was left by a set-up stopped while it created it: made again, not used half made.
if [ ! -x "$VENV/bin/python" ] || [ ! -x "$VENV/bin/pip" ]; then
  log "creating $VENV"
  rm -rf "$VENV"
  "$PYTHON" -m venv "$VENV"
fi
# uv installs the same pins in about half pip's time (from its cache on the next checkout). It
# compiles them to bytecode as pip does: where PYTHONDONTWRITEBYTECODE is set (it is on these
# machines), a module without it is compiled again by every process that imports it, which made a
# loaded test suite a third slower. It does not read pip's configuration, so the indexes, find-links and CA file pip is
# configured with are handed to it; if uv cannot install, pip does.
UV_VERSION=0.9.5
pip_setting() { "$VENV/bin/pip" config get "global.$1" 2>/dev/null || true; }
install_requirements() {
  "$VENV/bin/pip" install -q --disable-pip-version-check "uv==$UV_VERSION" 2>&1 | { grep -v "is ignored: it is neither" || true; }
  local args=(--python "$VENV/bin/python" --index-strategy unsafe-best-match --compile-bytecode -r requirements.txt) url
  url=$(pip_setting index-url); [ -z "$url" ] || args+=(--index-url "$url")
  for url in $(pip_setting extra-index-url); do args+=(--extra-index-url "$url"); done
  for url in $(pip_setting find-links); do args+=(--find-links "$url"); done
  local cert; cert=$(pip_setting cert)
  if env ${cert:+SSL_CERT_FILE="$cert"} "$VENV/bin/uv" pip install -q "${args[@]}"; then return 0; fi
  log "uv could not install requirements.txt: installing with pip"
  "$VENV/bin/pip" install -q --disable-pip-version-check -r requirements.txt 2>&1 | { grep -v "is ignored: it is neither" || true; }
}
h=$(hash_of requirements.txt)
if step_needed pip "$h"; then
  log "installing Python dependencies (requirements.txt)"
  install_requirements
  step_done pip "$h"
fi

# Built artifacts that take long to make are kept in the user's cache, each under a key of
# everything that goes into it: another checkout on this machine (a fresh clone in CI) unpacks them
# in a second instead of building them again, as ccache and uv do for their parts. Unused for 30
# days, they are removed.
CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/caretaker
mkdir -p "$CACHE"
find "$CACHE" -type f -mtime +30 -delete

# cache_put FILE KEY_PATH: FILE into the cache as KEY_PATH, atomically (checkouts may set up at once).
cache_put() { mkdir -p "$(dirname "$2")"; cp "$1" "$2.$$" && mv -f "$2.$$" "$2"; }

# 3. ROS 2 interface packages, generated with rosidl into the venv. The wheels' exported CMake
#    targets hard-code the manylinux build paths of Python and numpy: point them at ours. The
#    generated C and C++ (hundreds of files, most of a fresh checkout's set-up time) compile
#    through ccache, with paths taken relative to the checkout. A package's installed files are
#    cached (relative to the venv, keyed by its sources, the pinned dependencies and the Python);
#    its exported CMake files name the venv they were built for, rewritten on unpacking.
INTERFACE_PACKAGES=(python/at_ros/affordance_template_msgs sim/caretaker_sim_msgs python/bridge/caretaker_ledger_msgs
                    python/onboard/caretaker_onboard_msgs python/perception/caretaker_perception_msgs)
h=$(hash_of "${INTERFACE_PACKAGES[@]}" requirements.txt)
if step_needed interfaces "$h"; then
  py_include=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  np_include=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
  { grep -rlE '/opt/python/cp311-cp311' "$VENV"/share/*/cmake/ 2>/dev/null || true; } | while read -r f; do
    sed -i -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_include#g" \
           -e "s#/opt/python/cp311-cp311/include/python3.11#$py_include#g" "$f"
  done
  # The packages do not depend on each other: built side by side, one's single-threaded code
  # generation overlaps another's compiling.
  build_interfaces() {
    local pkg=$1 name build key archive built_for
    name=$(basename "$pkg")
    key=$( { hash_of "$pkg" requirements.txt; "$VENV/bin/python" -VV; } | sha256sum | cut -c1-16)
    archive=$CACHE/interfaces/$name-$key.tar
    if [ -f "$archive" ] && [ -f "$archive.venv" ]; then
      built_for=$(cat "$archive.venv")
      tar -xf "$archive" -C "$VENV" && touch "$archive" "$archive.venv" || return 1
      { grep -rlF "$built_for" "$VENV/share/$name" || true; } | while read -r f; do sed -i "s#$built_for#$VENV#g" "$f"; done
      log "ROS interfaces $name from the cache"
      return 0
    fi
    log "building ROS interfaces $name"
    build=$ROOT/build/rosidl/$name
    rm -rf "$build"; mkdir -p "$build"
    CMAKE_PREFIX_PATH=$VENV AMENT_PREFIX_PATH=$VENV cmake -S "$pkg" -B "$build" \
      -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$VENV/bin/python" \
      -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
      -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release > "$build.log" 2>&1 \
      && CCACHE_BASEDIR=$ROOT cmake --build "$build" -j 2 >> "$build.log" 2>&1 \
      && cmake --install "$build" >> "$build.log" 2>&1 \
      || { tail -40 "$build.log"; log "building $name failed: see $build.log"; return 1; }
    sed "s#^$VENV/##" "$build/install_manifest.txt" | tar -cf "$build.tar" -C "$VENV" -T - \
      && echo "$VENV" > "$build.venv" && cache_put "$build.venv" "$archive.venv" && cache_put "$build.tar" "$archive" \
      || log "could not cache ROS interfaces $name (the next checkout builds them again)"
    log "built ROS interfaces $name"
  }
  builds=()
  for pkg in "${INTERFACE_PACKAGES[@]}"; do
    build_interfaces "$pkg" & builds+=($!)
  done
  failed=0
  for build in "${builds[@]}"; do wait "$build" || failed=1; done
  [ $failed -eq 0 ] || exit 1
  step_done interfaces "$h"
fi

# 4. The caretaker distribution itself (editable, so the checkout is what runs).
h=$(hash_of pyproject.toml)
if step_needed caretaker "$h"; then
  log "installing the caretaker package (editable)"
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps -e . 2>&1 | { grep -v "is ignored: it is neither" || true; }
  step_done caretaker "$h"
fi
# The checkout's own Python as bytecode too, for the same reason (only changed files, in a second).
"$VENV/bin/python" -m compileall -q -j 0 python sim > /dev/null

# 5. The Java PAX plugins, built offline against Debian's Maven repository (.mvn/maven.config).
if [ -f pom.xml ]; then
  h=$(hash_of pom.xml .mvn java)
  jar=java/pax-plugins/target/pax-plugins.jar
  if step_needed java "$h" || [ ! -f $jar ]; then
    cached=$CACHE/java/pax-plugins-$( { echo "$h"; javac -version 2>&1; } | sha256sum | cut -c1-16).jar
    if [ -f "$cached" ]; then
      mkdir -p "$(dirname $jar)" && cp "$cached" $jar && touch "$cached"
      log "the Java PAX plugins from the cache"
    else
      log "building the Java PAX plugins (mvn package)"
      mvn -q package -DskipTests
      cache_put $jar "$cached"
    fi
    step_done java "$h"
  fi
fi

# 6. Node test clients (roslibjs) from the npm registry.
if [ -f tests/js/package.json ]; then
  h=$(hash_of tests/js/package.json tests/js/package-lock.json)
  if step_needed npm "$h" || [ ! -d tests/js/node_modules ]; then
    log "installing Node test clients (npm ci)"
    (cd tests/js && npm ci --silent --no-audit --no-fund)
    step_done npm "$h"
  fi
fi

# 7. The web view's 3D view: three.js and urdf-loader from the npm registry, bundled by esbuild
#    (its Linux binary is an npm package too) into python/console/static/spatial.js.
SPATIAL=python/console/spatial
SPATIAL_BUNDLE=python/console/static/spatial.js
if [ -f $SPATIAL/package.json ]; then
  h=$(hash_of $SPATIAL/package.json $SPATIAL/package-lock.json)
  if step_needed spatial-npm "$h" || [ ! -d $SPATIAL/node_modules ]; then
    log "installing the 3D view's packages (npm ci)"
    (cd $SPATIAL && npm ci --silent --no-audit --no-fund)
    step_done spatial-npm "$h"
  fi
  h=$(hash_of $SPATIAL/package.json $SPATIAL/package-lock.json $SPATIAL/src)
  if step_needed spatial-bundle "$h" || [ ! -f $SPATIAL_BUNDLE ]; then
    log "bundling the 3D view ($SPATIAL_BUNDLE)"
    (cd $SPATIAL && npm run --silent build)
    step_done spatial-bundle "$h"
  fi
fi

log "ready"
