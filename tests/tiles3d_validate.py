#!/usr/bin/python3
"""Validates a 3D Tiles 1.1 tileset written by `skyfall export 3dtiles`, offline.

Usage: tiles3d_validate.py TILESET.json SCHEMAS_DIR

Checks tileset.json against the official 3D Tiles 1.1 JSON schemas (from
SCHEMAS_DIR/3d-tiles-1.1, registered locally: nothing is fetched), then the
rules the schemas cannot express: every content file exists, geometricError
never grows from a parent to a child, leaves have 0, the root refines with
REPLACE and carries a 16-number transform, and the tileset lists the splat
extensions for its glTF content. Exits 1 listing every problem.
"""
import glob
import json
import os
import sys

import jsonschema

BASE = "https://schemas.skyfall.invalid/3d-tiles-1.1/"


def load_store(schemas_dir):
    root = os.path.join(schemas_dir, "3d-tiles-1.1")
    store = {}
    for path in glob.glob(os.path.join(root, "**", "*.schema.json"), recursive=True):
        with open(path) as f:
            doc = json.load(f)
        # The files' $id are bare file names; give each its place in the tree
        # so that relative $refs resolve from the file's own folder.
        uri = BASE + os.path.relpath(path, root).replace(os.sep, "/")
        store[uri] = dict(doc, **{"$id": uri})
    return store


def make_validator(store, uri):
    schema = store[uri]
    cls = jsonschema.validators.validator_for(schema)
    try:
        import referencing
        import referencing.jsonschema
    except ImportError:
        return cls(schema, resolver=jsonschema.RefResolver(base_uri=uri, referrer=schema, store=store))
    registry = referencing.Registry().with_resources(
        (u, referencing.Resource.from_contents(d, default_specification=referencing.jsonschema.DRAFT202012))
        for u, d in store.items())
    return cls(schema, registry=registry)


def walk(node, here, problems, counts, parent_error=None, path="root"):
    counts["tiles"] += 1
    error = node["geometricError"]
    if parent_error is not None and error > parent_error + 1e-9:
        problems.append(f"{path}: geometricError {error} > its parent's {parent_error}")
    content = node.get("content")
    if content:
        counts["contents"] += 1
        if not os.path.isfile(os.path.join(here, content["uri"])):
            problems.append(f"{path}: content {content['uri']} does not exist")
    children = node.get("children", [])
    if not children and error != 0:
        problems.append(f"{path}: a leaf with geometricError {error} (must be 0)")
    for i, child in enumerate(children):
        walk(child, here, problems, counts, error, f"{path}/{i}")


def main(tileset_path, schemas_dir):
    store = load_store(schemas_dir)
    with open(tileset_path) as f:
        tileset = json.load(f)
    validator = make_validator(store, BASE + "tileset.schema.json")
    problems = [f"schema: {'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(tileset)]
    if problems:  # the rules below assume a schema-valid tileset
        for p in problems:
            print("problem:", p)
        return 1
    root = tileset["root"]
    if root.get("refine") != "REPLACE":
        problems.append(f"root refine is {root.get('refine')!r}, not REPLACE")
    if len(root.get("transform", [])) != 16:
        problems.append("root has no 16-number transform")
    gltf_ext = tileset.get("extensions", {}).get("3DTILES_content_gltf", {})
    for needed in ("KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"):
        for key in ("extensionsUsed", "extensionsRequired"):
            if needed not in gltf_ext.get(key, []):
                problems.append(f"3DTILES_content_gltf.{key} lacks {needed}")
    if "3DTILES_content_gltf" not in tileset.get("extensionsUsed", []):
        problems.append("extensionsUsed lacks 3DTILES_content_gltf")
    counts = {"tiles": 0, "contents": 0}
    walk(root, os.path.dirname(os.path.abspath(tileset_path)), problems, counts, tileset["geometricError"])
    print(f"{counts['tiles']} tile(s), {counts['contents']} content file(s) checked")
    for p in problems:
        print("problem:", p)
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
