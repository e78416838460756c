#!/usr/bin/python3
"""Validates the static STAC catalog of a skyfall run, offline.

Usage: stac_validate.py OUT/catalog.json SCHEMAS_DIR

Starting at the root catalog it follows every link (child, item, parent,
root, collection, self) and every asset, and for each document checks:
  - the STAC 1.1 core schema of its type and the schema of every extension it
    lists (schemas from SCHEMAS_DIR, registered under their $id: nothing is
    fetched from the network);
  - links and assets are relative and resolve to existing files;
  - every asset's file:size and file:checksum (SHA-256 multihash) match the
    file;
  - every GeoTIFF asset's proj:code, proj:shape and proj:transform match
    what `gdalinfo -json` reads from the file.
Prints one line per document and exits 1 listing every problem found.
"""
import glob
import hashlib
import json
import os
import subprocess
import sys

import jsonschema

STAC_ITEM_SPEC = "https://schemas.stacspec.org/v1.1.0/item-spec/json-schema/"
CORE = {
    "Catalog": "https://schemas.stacspec.org/v1.1.0/catalog-spec/json-schema/catalog.json",
    "Collection": "https://schemas.stacspec.org/v1.1.0/collection-spec/json-schema/collection.json",
    "Feature": "https://schemas.stacspec.org/v1.1.0/item-spec/json-schema/item.json",
}


def load_store(schemas_dir):
    store = {}
    for path in glob.glob(os.path.join(schemas_dir, "**", "*.json"), recursive=True):
        with open(path) as f:
            try:
                doc = json.load(f)
            except ValueError:
                continue
        if not isinstance(doc, dict) or "$id" not in doc:
            continue
        if os.sep + "stac-1.1.0" + os.sep in path and "item-spec" in doc["$id"]:
            # Other schemas reference these by file name next to item.json;
            # one upstream $id lacks the dot of its file name ("commonjson").
            doc = dict(doc, **{"$id": STAC_ITEM_SPEC + os.path.basename(path)})
        store[doc["$id"].rstrip("#")] = doc
    return store


def make_validator(schema, schema_id, store):
    """A validator that resolves every $ref from `store` (never the network):
    with the `referencing` library where jsonschema has it (4.18 and later),
    else with RefResolver (Debian 12's 4.10)."""
    cls = jsonschema.validators.validator_for(schema, default=jsonschema.Draft7Validator)
    try:
        import referencing
        import referencing.jsonschema
    except ImportError:
        return cls(schema, resolver=jsonschema.RefResolver(base_uri=schema_id, referrer=schema, store=store))
    draft7 = referencing.jsonschema.DRAFT7
    registry = referencing.Registry().with_resources(
        (uri, referencing.Resource.from_contents(doc, default_specification=draft7)) for uri, doc in store.items())
    return cls(schema, registry=registry)


def validate(doc, schema_id, store):
    schema = store[schema_id.rstrip("#")]
    return [f"{schema_id}: {'/'.join(map(str, e.absolute_path))}: {e.message}"
            for e in make_validator(schema, schema_id, store).iter_errors(doc)]


def sha256_multihash(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 16), b""):
            h.update(block)
    return "1220" + h.hexdigest()


def check_geotiff(path, asset):
    info = json.loads(subprocess.run(["gdalinfo", "-json", path], check=True, capture_output=True, text=True).stdout)
    problems = []
    gt = info["geoTransform"]
    expected = [gt[1], gt[2], gt[0], gt[4], gt[5], gt[3]]
    if any(abs(a - b) > 1e-9 * max(1.0, abs(b)) for a, b in zip(asset.get("proj:transform", []), expected)):
        problems.append(f"proj:transform {asset.get('proj:transform')} != gdalinfo {expected}")
    width, height = info["size"]
    if asset.get("proj:shape") != [height, width]:
        problems.append(f"proj:shape {asset.get('proj:shape')} != gdalinfo [{height}, {width}]")
    epsg = info.get("stac", {}).get("proj:epsg")
    if epsg is None:
        wkt = info["coordinateSystem"]["wkt"]
        epsg = int(wkt.rsplit('ID["EPSG",', 1)[1].split("]")[0])
    if asset.get("proj:code") != f"EPSG:{epsg}":
        problems.append(f"proj:code {asset.get('proj:code')} != gdalinfo EPSG:{epsg}")
    return problems


def main(root_path, schemas_dir):
    store = load_store(schemas_dir)
    problems = []
    seen, queue = set(), [os.path.abspath(root_path)]
    counts = {"Catalog": 0, "Collection": 0, "Feature": 0, "assets": 0}
    while queue:
        path = queue.pop()
        if path in seen:
            continue
        seen.add(path)
        here = os.path.dirname(path)
        with open(path) as f:
            doc = json.load(f)
        kind = doc.get("type")
        if kind not in CORE:
            problems.append(f"{path}: unknown type {kind!r}")
            continue
        counts[kind] += 1
        errors = validate(doc, CORE[kind], store)
        for ext in doc.get("stac_extensions", []):
            if ext.rstrip("#") not in store:
                errors.append(f"extension schema {ext} is not in {schemas_dir}")
            else:
                errors += validate(doc, ext, store)
        for link in doc.get("links", []):
            href = link["href"]
            if "://" in href or os.path.isabs(href):
                errors.append(f"link {link['rel']} is not relative: {href}")
                continue
            target = os.path.normpath(os.path.join(here, href))
            if not os.path.exists(target):
                errors.append(f"link {link['rel']} -> {href} does not exist")
            elif link["rel"] == "self" and target != path:
                errors.append(f"self link {href} is not this file")
            else:
                queue.append(target)
        for key, asset in doc.get("assets", {}).items():
            counts["assets"] += 1
            href = asset["href"]
            target = os.path.normpath(os.path.join(here, href))
            if "://" in href or os.path.isabs(href) or not os.path.isfile(target):
                errors.append(f"asset {key} -> {href} is not a relative path to a file")
                continue
            if asset.get("file:size") != os.path.getsize(target):
                errors.append(f"asset {key}: file:size {asset.get('file:size')} != {os.path.getsize(target)}")
            if asset.get("file:checksum") != sha256_multihash(target):
                errors.append(f"asset {key}: file:checksum does not match {href}")
            if asset.get("type", "").startswith("image/tiff"):
                errors += [f"asset {key}: {p}" for p in check_geotiff(target, asset)]
        print(f"{'ok  ' if not errors else 'FAIL'} {kind:10s} {os.path.relpath(path, os.path.dirname(os.path.abspath(root_path)))}")
        problems += [f"{path}: {e}" for e in errors]
    print(f"{counts['Catalog']} catalog(s), {counts['Collection']} collection(s), {counts['Feature']} item(s), "
          f"{counts['assets']} asset(s) checked")
    for p in problems:
        print("problem:", p)
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
