#!/usr/bin/env bash
# Fetch a real Foxglove web viewer for the live view's browser test
# (src/vizzy_runtime/test/test_live_view_browser.py), outside the repo.
#
#   scripts/viewer_test_setup.sh            # into ${VIZZY_VIEWER_CACHE:-~/.cache/vizzy-viewer}
#   apt-get install -y chromium             # the browser (Debian's; /usr/bin/chromium)
#
# What it fetches (pinned, each checked against the registry's sha512):
#   @foxglove/studio-base 1.48.0  its assets/ is the built web app of Foxglove Studio 1.48 as a
#                                 UMD library (React and ReactDOM left out): the test serves it
#                                 with a small page of its own that mounts the app (App, the
#                                 Foxglove WebSocket data source, an in-memory layout storage)
#   react, react-dom 17.0.2       the versions studio-base 1.48 was built against (UMD builds)
#   playwright-core 1.57.0        drives Debian's chromium (never `npx playwright install`: that
#                                 downloads browsers of its own)
# Nothing is installed into the repo or the Python environment. Idempotent: a package already
# unpacked is kept.
set -euo pipefail

CACHE="${VIZZY_VIEWER_CACHE:-$HOME/.cache/vizzy-viewer}"
PACKAGES=(
  "@foxglove/studio-base@1.48.0 sha512-EY8cYoHUm6VyTSVZBdfn5EJK2bRwTfAjH92H5wgAEcnKyeCUyKkxjgwbqO2jKwRJGa+7VPaEHHF167BzFh+N4A=="
  "react@17.0.2 sha512-gnhPt75i/dq/z3/6q/0asP78D0u592D5L1pd7M8P+dck6Fu/jJeL6iVVK23fptSUZj8Vjf++7wXA8UNclGQcbA=="
  "react-dom@17.0.2 sha512-s4h96KtLDUQlsENhMn1ar8t2bEa+q/YAtj8pPPdIjPDGBDIVNsrD9aXNWqspUe6AzKCIG0C1HZZLqLV7qpOBGA=="
  "playwright-core@1.57.0 sha512-agTcKlMw/mjBWOnD6kFZttAAGHgi/Nw0CZ2o6JqWSbMlI219lAFLZZCyqByTsvVAJq5XA5H8cA6PrvBRpBWEuQ=="
)

command -v npm >/dev/null || { echo "viewer_test_setup: npm not found (apt-get install -y npm)" >&2; exit 1; }
mkdir -p "$CACHE/tarballs"
for entry in "${PACKAGES[@]}"; do
  spec="${entry%% *}"
  want="${entry#* }"
  name="${spec%@*}"
  dest="$CACHE/$(echo "$spec" | tr '/@' '__')"
  if [[ -f "$dest/package.json" ]]; then
    echo "viewer_test_setup: $spec: present in $dest"
    continue
  fi
  tarball="$(cd "$CACHE/tarballs" && npm pack --silent "$spec" | tail -1)"
  got="sha512-$(openssl dgst -sha512 -binary "$CACHE/tarballs/$tarball" | base64 -w0)"
  if [[ "$got" != "$want" ]]; then
    echo "viewer_test_setup: $spec: sha512 differs from the pinned one ($got): not unpacked" >&2
    exit 1
  fi
  rm -rf "$dest.tmp" && mkdir -p "$dest.tmp"
  tar -xzf "$CACHE/tarballs/$tarball" -C "$dest.tmp" --strip-components=1
  mv "$dest.tmp" "$dest"
  echo "viewer_test_setup: $name: unpacked into $dest"
done
if ! command -v chromium >/dev/null; then
  echo "viewer_test_setup: no chromium yet: apt-get install -y chromium" >&2
fi
echo "viewer_test_setup: done; run: .venv/bin/python -m pytest src/vizzy_runtime/test/test_live_view_browser.py"
