#!/usr/bin/env bash
# A finished campaign is kept as one archive, results/<name>.tar.xz, holding what its tables are
# computed from: each run's config.toml, progress.csv, episodes.csv and marker, and each sweep's
# sweep.toml and cells.csv (no checkpoints, logs or locks). The scripts that read a campaign
# unpack it first into results/<name>/, which then ignores itself in git (a `.gitignore` of `*`);
# a campaign extended by hand is packed again.
#   bash scripts/results.sh unpack NAME...  results/NAME.tar.xz -> results/NAME/; nothing to do
#                                           when that folder was unpacked from this archive
#   bash scripts/results.sh pack NAME       results/NAME/ -> results/NAME.tar.xz, then prints
#                                           the git commands that track the archive in its place
#   bash scripts/results.sh need PATH...    unpacks the archive of each PATH under results/NAME/
#                                           that has one (what the report scripts call first)
#   bash scripts/results.sh list            each archive: size, files, runs, and whether unpacked
# Needs GNU tar and xz (xz-utils). Archives are reproducible: sorted names, no owners or times.
set -euo pipefail
caller=$PWD
cd "$(dirname "$0")/.."
repo=$PWD
root=results
die() { echo "error: $*" >&2; exit 2; }
valid() {
  case $1 in
    '' | */* | .* ) die "'$1' is not a campaign name: a folder name under $root/ (for example guard-campaign)" ;;
  esac
}
stamp() { sha256sum "$1" | cut -d' ' -f1; }

unpack() {
  local name=$1 archive="$root/$1.tar.xz" dir="$root/$1"
  [ -f "$archive" ] || die "$archive is missing (the archives: bash scripts/results.sh list)"
  local want; want=$(stamp "$archive")
  if [ -e "$dir" ] || [ -L "$dir" ]; then
    [ -d "$dir" ] && [ ! -L "$dir" ] || die "$dir is not a folder: move it away to unpack $archive"
    local have; have=$(cat "$dir/.archive" 2>/dev/null || true)
    [ "$have" = "$want" ] && return 0
    if [ -z "$have" ]; then
      die "$dir exists and was not unpacked from $archive (runs being added?): pack it with \`bash scripts/results.sh pack $name\`, or move it away to unpack the archive"
    fi
    die "$dir was unpacked from another version of $archive: pack it again with \`bash scripts/results.sh pack $name\` if it holds new runs, or move it away to unpack this version"
  fi
  tmp="$root/.$name.unpacking.$$"
  trap 'rm -rf "$tmp"' EXIT
  mkdir "$tmp"
  xz -dc "$archive" | tar -x -C "$tmp" --no-same-owner
  [ -d "$tmp/$name" ] || die "$archive does not hold a folder $name/"
  printf '*\n' > "$tmp/$name/.gitignore"
  echo "$want" > "$tmp/$name/.archive"
  sync -f "$tmp/$name" 2>/dev/null || sync
  mv -T "$tmp/$name" "$dir"
  rm -rf "$tmp"
  trap - EXIT
  echo "unpacked $archive into $dir/ ($(find "$dir" -name progress.csv | wc -l) runs)" >&2
}

pack() {
  local name=$1 archive="$root/$1.tar.xz" dir="$root/$1"
  [ -d "$dir" ] && [ ! -L "$dir" ] || die "$dir is not a folder"
  tmp="$archive.tmp.$$"
  trap 'rm -f "$tmp"' EXIT
  # the kept files only, in a fixed order, without owners or times
  (cd "$root" && find "$name" -type f \
      \( -name config.toml -o -name progress.csv -o -name episodes.csv -o -name .apo-run \
         -o -name sweep.toml -o -name cells.csv -o -name error.txt \) -print0 \
    | LC_ALL=C sort -z \
    | tar --null --no-recursion --mtime=@0 --owner=0 --group=0 --numeric-owner -cf - -T -) \
    | xz -9 -T1 > "$tmp"
  sync "$tmp" 2>/dev/null || sync
  mv -f "$tmp" "$archive"
  trap - EXIT
  [ -f "$dir/.gitignore" ] || printf '*\n' > "$dir/.gitignore"
  stamp "$archive" > "$dir/.archive"
  echo "packed $dir/ into $archive ($(du -h "$archive" | cut -f1), $(xz -dc "$archive" | tar -t | grep -c 'progress.csv$') runs)"
  if git ls-files --error-unmatch "$dir" > /dev/null 2>&1; then
    echo "the folder's files are still tracked; to track the archive in their place:"
    echo "  git rm -r -q --cached $dir && git add $archive"
  fi
}

# the campaign a path lies in, when it is results/NAME[/...] and results/NAME.tar.xz exists
need() {
  local path name
  for path in "$@"; do
    case $path in /*) ;; *) path=$caller/$path ;; esac
    path=$(realpath -m --relative-to="$repo" "$path")
    case $path in "$root"/*) ;; *) continue ;; esac
    name=${path#"$root"/}
    name=${name%%/*}
    [ -n "$name" ] && [ -f "$root/$name.tar.xz" ] && unpack "$name"
  done
  return 0
}

list() {
  local found=0
  for archive in "$root"/*.tar.xz; do
    [ -f "$archive" ] || continue
    found=1
    local name; name=$(basename "$archive" .tar.xz)
    local files; files=$(xz -dc "$archive" | tar -t | grep -cv '/$')
    local runs; runs=$(xz -dc "$archive" | tar -t | grep -c 'progress.csv$')
    local state="packed"
    if [ -d "$root/$name" ]; then
      if [ "$(cat "$root/$name/.archive" 2>/dev/null)" = "$(stamp "$archive")" ]; then
        state="unpacked in $root/$name/"
      else
        state="$root/$name/ differs from the archive"
      fi
    fi
    printf '%-20s %6s  %5d files  %4d runs  %s\n' "$name" "$(du -h "$archive" | cut -f1)" "$files" "$runs" "$state"
  done
  [ $found = 1 ] || echo "no archives in $root/"
}

command -v xz > /dev/null || die "xz is missing: apt-get install xz-utils"
case ${1:-} in
  unpack) shift; [ $# -gt 0 ] || die "unpack needs a campaign name"; for n in "$@"; do valid "$n"; unpack "$n"; done ;;
  pack) [ $# -eq 2 ] || die "pack takes one campaign name"; valid "$2"; pack "$2" ;;
  need) shift; need "$@" ;;
  list) list ;;
  *) die "usage: bash scripts/results.sh unpack NAME... | pack NAME | need PATH... | list" ;;
esac
