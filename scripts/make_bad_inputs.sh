#!/usr/bin/env bash
# Writes the bad-input corpus: a DFC2019-style tree in which each AOI carries
# one kind of defect (plus one sound AOI), and one image-level AOI whose
# images are broken in every way a folder of satellite crops can be.
# `skyfall run` over it must process the sound AOIs and name every defect;
# docs/reliability.md lists each case with its outcome, and the test
# `Cli.BadInputCorpusNamesEveryDefect` checks them.
#
#   scripts/make_bad_inputs.sh OUT [SKYFALL]
#
# OUT is created (it must not exist yet); SKYFALL defaults to build/bin/skyfall.
# Needs gdal-bin (gdal_translate) and coreutils; the scenes are small (64 m,
# 3 views) so the whole corpus is written in a few seconds.
set -euo pipefail
if [ $# -lt 1 ]; then
  echo "usage: $0 OUT [SKYFALL]" >&2
  exit 2
fi
OUT=$1
SKYFALL=${2:-$(cd "$(dirname "$0")/.." && pwd)/build/bin/skyfall}
if [ -e "$OUT" ]; then
  echo "make_bad_inputs: $OUT exists; give a new folder" >&2
  exit 1
fi
[ -x "$SKYFALL" ] || { echo "make_bad_inputs: no skyfall binary at $SKYFALL (build first)" >&2; exit 1; }
command -v gdal_translate >/dev/null || { echo "make_bad_inputs: gdal_translate missing (scripts/setup.sh installs gdal-bin)" >&2; exit 1; }

mkdir -p "$OUT/Track3-RGB-crops" "$OUT/Track3-Truth" "$OUT/satnerf-rpcs"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
CROPS=$OUT/Track3-RGB-crops
TRUTH=$OUT/Track3-Truth

# synth NAME LON [extra synth flags]: a 64 m scene with 3 views at (30.35 N,
# LON), moved into the corpus. AOIs sit kilometres apart so that each forms
# its own city and one AOI's failure is visibly its own.
synth() {
  local name=$1 lon=$2
  shift 2
  "$SKYFALL" --quiet synth --out "$WORK/$name" --aoi "$name" --size-m 64 --views 3 --lat 30.35 --lon "$lon" "$@" >/dev/null
  mv "$WORK/$name/Track3-RGB-crops/$name" "$CROPS/"
  mv "$WORK/$name/Track3-Truth/$name"_* "$TRUTH/"
  mv "$WORK/$name/satnerf-rpcs/$name" "$OUT/satnerf-rpcs/"
}

# rpb_edit SRC DST AWK_PROGRAM: DST is SRC with its RPC moved to an .RPB
# sidecar (GDAL reads it when the TIFF has no RPC tag), edited by the awk
# program. The Sat-NeRF JSON would stand in for a broken RPC, so it goes.
rpb_edit() {
  local src=$1 dst=$2 program=$3
  gdal_translate -q -co PROFILE=BASELINE "$src" "$dst"
  local rpb=${dst%.tif}.RPB
  awk "$program" "$rpb" >"$rpb.new" && mv "$rpb.new" "$rpb"
  rm -f "$OUT/satnerf-rpcs/$(basename "$(dirname "$dst")")/$(basename "${dst%.tif}").json"
}

# A sound AOI: the control that must come through.
synth GOOD_001 -81.66

# AOI on the boundary of UTM zones 17 and 18 (78 W): processed as any other.
synth ZONE_001 -78.0

# Truth grid descriptions that cannot be read.
synth TXTFIELDS_001 -81.61
printf '%s\n' 0.000000 0.000000 128.000000 >"$TRUTH/TXTFIELDS_001_DSM.txt"
synth TXTNEG_001 -81.56
sed -i '3s/.*/-128.000000/' "$TRUTH/TXTNEG_001_DSM.txt"
synth TXTTEXT_001 -81.51
sed -i '1s/.*/easting/' "$TRUTH/TXTTEXT_001_DSM.txt"
# A truth DSM whose size disagrees with its _DSM.txt.
synth TRUTHSIZE_001 -81.46
gdal_translate -q -outsize 50% 50% "$TRUTH/TRUTHSIZE_001_DSM.tif" "$WORK/half.tif"
mv "$WORK/half.tif" "$TRUTH/TRUTHSIZE_001_DSM.tif"

# An AOI folder with no image.
mkdir -p "$CROPS/EMPTY_001"

# An AOI of one image: nothing to triangulate.
synth ONE_001 -81.41
rm "$CROPS/ONE_001/ONE_001_002_RGB.tif" "$CROPS/ONE_001/ONE_001_003_RGB.tif"

# Images that do not overlap: two views of one place, one of another 5 km away.
synth APART_001 -81.36
synth APARTB_001 -81.31
mv "$CROPS/APARTB_001/APARTB_001_001_RGB.tif" "$CROPS/APART_001/APART_001_004_RGB.tif"
rm -rf "$CROPS/APARTB_001" "$TRUTH"/APARTB_001_* "$OUT/satnerf-rpcs/APARTB_001"
rm "$CROPS/APART_001/APART_001_003_RGB.tif"

# One AOI with three sound images and every kind of broken image beside them.
synth IMAGES_001 -81.26
D=$CROPS/IMAGES_001
GOODIMG=$D/IMAGES_001_001_RGB.tif
head -c 3000 "$GOODIMG" >"$D/IMAGES_001_004_RGB.tif"                       # truncated TIFF
{ printf 'NOTATIFF'; tail -c +9 "$GOODIMG"; } >"$D/IMAGES_001_005_RGB.tif"   # wrong magic
rpb_edit "$GOODIMG" "$D/IMAGES_001_006_RGB.tif" '/heightOffset/ {print "\theightOffset = nan;"; next} {print}'
rpb_edit "$GOODIMG" "$D/IMAGES_001_007_RGB.tif" '/longScale/ {print "\tlongScale = 0;"; next} {print}'
# Vanishing denominator: the line denominator becomes 0 + 0.001 L, zero at
# the normalization centre (the synthetic RPC's denominator may be its
# constant term alone, so zeroing that term only would zero all 20).
rpb_edit "$GOODIMG" "$D/IMAGES_001_008_RGB.tif" \
  'den == 1 && /[0-9]/ {print "\t\t\t0,"; den = 2; next} den == 2 && /[0-9]/ {print "\t\t\t0.001,"; den = 0; next} /lineDenCoef/ {den = 1} {print}'
cp "$GOODIMG" "$D/IMAGES_001_009_RGB.tif"                                   # duplicate image
gdal_translate -q -srcwin 0 0 1 1 "$GOODIMG" "$D/IMAGES_001_010_RGB.tif"     # 1x1 image
gdal_translate -q -scale 0 255 0 0 "$GOODIMG" "$D/IMAGES_001_011_RGB.tif"    # all black
# A huge sparse image: the sound image in the corner of a 40000 x 40000
# canvas (a VRT: 4.8 GB of pixels on paper, a few hundred bytes on disk).
gdal_translate -q -of VRT "$GOODIMG" "$WORK/huge.vrt"
sed -e 's/rasterXSize="[0-9]*"/rasterXSize="40000"/' -e 's/rasterYSize="[0-9]*"/rasterYSize="40000"/' \
  -e "s#>[^<]*IMAGES_001_001_RGB.tif<#>$GOODIMG<#" -e 's/relativeToVRT="1"/relativeToVRT="0"/' \
  "$WORK/huge.vrt" >"$D/IMAGES_001_012_RGB.vrt"

echo "make_bad_inputs: wrote $OUT ($(find "$CROPS" -mindepth 1 -maxdepth 1 -type d | wc -l) AOIs)"
