#!/usr/bin/env bash
# debian-fetch.sh SUITE DESTDIR PKG...
# Downloads Debian packages from another suite (e.g. trixie, bookworm-backports)
# with a private apt list built from the mirror URI of this machine's own apt
# sources, then unpacks them into DESTDIR. The system's apt state is untouched.
# The .deb files are cached under .cache/debs so a second run needs no network.
set -euo pipefail
suite=$1; dest=$2; shift 2
top=$(cd "$(dirname "$0")/.." && pwd)
cache=${CONTOUR_CACHE:-$top/.cache}
aptdir=$cache/apt-$suite
debs=$cache/debs
mkdir -p "$debs" "$dest"

have_all=1
for p in "$@"; do
  ls "$debs/${p}"_*.deb >/dev/null 2>&1 || have_all=0
done

if [ "$have_all" = 0 ]; then
  mirror=$( { awk '/^URIs:/{print $2}' /etc/apt/sources.list.d/*.sources 2>/dev/null
              awk '/^deb /{for(i=2;i<=NF;i++) if ($i ~ /:\/\//) {print $i; break}}' /etc/apt/sources.list 2>/dev/null
            } | grep -v -- '-security' | head -n 1 || true)
  if [ -z "$mirror" ]; then
    echo "debian-fetch: no Debian mirror found in this machine's apt sources" >&2
    exit 1
  fi
  mkdir -p "$aptdir/lists/partial" "$aptdir/archives/partial" "$aptdir/etc"
  echo "deb $mirror $suite main" > "$aptdir/etc/sources.list"
  opts=(-o Dir::Etc::SourceList="$aptdir/etc/sources.list"
        -o Dir::Etc::SourceParts=/dev/null
        -o Dir::State::Lists="$aptdir/lists"
        -o Dir::Cache="$aptdir"
        -o Dir::Cache::archives="$aptdir/archives"
        -o APT::Get::List-Cleanup=0
        -o Debug::NoLocking=1
        -o APT::Sandbox::User=root)
  apt-get "${opts[@]}" -qq update
  (cd "$debs" && apt-get "${opts[@]}" -qq download "$@")
fi

for p in "$@"; do
  deb=$(ls -t "$debs/${p}"_*.deb | head -n 1)
  dpkg-deb -x "$deb" "$dest"
done
