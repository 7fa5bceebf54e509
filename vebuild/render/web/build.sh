#!/bin/sh
# Rebuild three-bundle.min.js (and THREE-LICENSE) from the versions pinned in package.json:
#
#   sh vebuild/render/web/build.sh
#
# Needs node and npm, and the npm registry once; installs into a temporary folder, so nothing but
# the two output files changes here. The result is committed: the exported viewer needs no network.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "$here/package.json" "$here/entry.js" "$work/"
cd "$work"
npm install --no-audit --no-fund --loglevel=error >/dev/null
three=$(node -p "JSON.parse(require('fs').readFileSync('node_modules/three/package.json')).version")
esb=$(node -p "JSON.parse(require('fs').readFileSync('node_modules/esbuild/package.json')).version")
npx --no-install esbuild entry.js --bundle --minify --format=iife --global-name=VEBUILD_THREE \
  --target=es2020 --legal-comments=none \
  --banner:js="/* three.js ${three} (MIT, see THREE-LICENSE), bundled by esbuild ${esb} from vebuild/render/web/entry.js; rebuild: sh vebuild/render/web/build.sh */" \
  --outfile="$work/three-bundle.min.js" --log-level=warning
cp "$work/three-bundle.min.js" "$here/three-bundle.min.js"
cp "$work/node_modules/three/LICENSE" "$here/THREE-LICENSE"
echo "wrote $here/three-bundle.min.js ($(wc -c < "$here/three-bundle.min.js") bytes, three $three, esbuild $esb)"
