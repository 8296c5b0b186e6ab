#!/usr/bin/env python3
"""Validate Kubernetes objects against a CRD's openAPIV3Schema, and extract the part of
KubeRay's RayJob schema that our manifest uses (the extract is committed, so the test
needs no KubeRay checkout).

    # refresh cluster/schemas/rayjob-v1.json from a KubeRay checkout at a release tag
    python cluster/kuberay_schema.py extract --crd KUBERAY/ray-operator/config/crd/bases/ray.io_rayjobs.yaml \\
        --source "ray-project/kuberay v1.7.0 (59d663aeec13760646da3db9c1cf8cfe883e30b7)"
    # check the manifest against a full CRD or the extract
    python cluster/kuberay_schema.py check [--crd FILE]

Validation is what `kubectl apply` gets from the API server for a custom resource: the
JSON-schema keywords of the openAPIV3Schema (types, enums, patterns, required, ...) plus
strict field validation (a field the schema does not declare is an error; Kubernetes
would otherwise prune it silently). Not evaluated: the CEL rules
(x-kubernetes-validations) and the operator's own checks.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Iterable

import yaml

HERE = Path(__file__).resolve().parent
MANIFEST = HERE / "kuberay-rayjob.yaml"
EXTRACT = HERE / "schemas" / "rayjob-v1.json"


def crd_schema(crd_file: str | Path, version: str = "v1") -> dict[str, Any]:
    """The openAPIV3Schema of one version of a CustomResourceDefinition file."""
    crd = yaml.safe_load(Path(crd_file).read_text())
    for v in crd["spec"]["versions"]:
        if v["name"] == version:
            return v["schema"]["openAPIV3Schema"]
    raise ValueError(f"{crd_file}: no version {version}")


def extract_schema() -> dict[str, Any]:
    """The committed extract's schema."""
    return json.loads(EXTRACT.read_text())["schema"]


def documents(path: str | Path = MANIFEST) -> list[dict[str, Any]]:
    return [d for d in yaml.safe_load_all(Path(path).read_text()) if d]


def unknown_fields(value: Any, schema: dict[str, Any], path: str = "") -> list[str]:
    """Fields of `value` that `schema` does not declare (strict field validation)."""
    if isinstance(value, dict):
        if schema.get("x-kubernetes-preserve-unknown-fields"):
            return []
        props = schema.get("properties")
        extra = schema.get("additionalProperties")
        out = []
        for key, sub in value.items():
            where = f"{path}.{key}" if path else key
            if props is not None and key in props:
                out += unknown_fields(sub, props[key], where)
            elif isinstance(extra, dict):
                out += unknown_fields(sub, extra, where)
            elif props is not None or extra is False:
                out.append(where)
            # no properties and no additionalProperties: an open object (e.g. top-level metadata)
        return out
    if isinstance(value, list) and isinstance(schema.get("items"), dict):
        return [e for i, item in enumerate(value) for e in unknown_fields(item, schema["items"], f"{path}[{i}]")]
    return []


def validate(obj: dict[str, Any], schema: dict[str, Any]) -> list[str]:
    """Every problem with `obj` under `schema`, as 'path: message' lines (empty: valid)."""
    import jsonschema

    validator = jsonschema.Draft4Validator(schema)
    errors = [f"{_path(e.absolute_path) or '<root>'}: {e.message}"
              for e in sorted(validator.iter_errors(obj), key=lambda e: list(map(str, e.absolute_path)))]
    errors += [f"{f}: field not declared by the schema" for f in unknown_fields(obj, schema)]
    return errors


def _path(parts: Iterable[Any]) -> str:
    out = ""
    for part in parts:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def trim(schema: dict[str, Any], instances: Iterable[Any]) -> dict[str, Any]:
    """The part of `schema` that `instances` use: used properties recursively, unused
    properties as {} (their names stay, so strict validation still knows them)."""
    instances = list(instances)
    out = {k: v for k, v in schema.items() if k not in ("properties", "items", "additionalProperties")}
    if "properties" in schema:
        used = {k for i in instances if isinstance(i, dict) for k in i}
        out["properties"] = {
            k: trim(sub, [i[k] for i in instances if isinstance(i, dict) and k in i]) if k in used else {}
            for k, sub in schema["properties"].items()
        }
    if isinstance(schema.get("items"), dict):
        out["items"] = trim(schema["items"], [e for i in instances if isinstance(i, list) for e in i])
    if isinstance(schema.get("additionalProperties"), dict):
        out["additionalProperties"] = trim(schema["additionalProperties"],
                                           [v for i in instances if isinstance(i, dict) for v in i.values()])
    elif "additionalProperties" in schema:
        out["additionalProperties"] = schema["additionalProperties"]
    return out


def rayjobs(docs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [d for d in docs if d.get("kind") == "RayJob"]


def cmd_extract(args: argparse.Namespace) -> int:
    schema = crd_schema(args.crd)
    jobs = rayjobs(documents(args.manifest))
    errors = [e for job in jobs for e in validate(job, schema)]
    if errors:  # never extract for an invalid manifest: the extract would hide the errors
        print("\n".join(errors), file=sys.stderr)
        return 1
    payload = {
        "_about": [
            "Extract of the openAPIV3Schema (version v1) of KubeRay's RayJob CustomResourceDefinition,",
            "ray-operator/config/crd/bases/ray.io_rayjobs.yaml, from " + args.source + ".",
            "Copyright The KubeRay Authors; licensed under the Apache License, Version 2.0",
            "(https://www.apache.org/licenses/LICENSE-2.0). Modified: trimmed by cluster/kuberay_schema.py",
            "to the properties cluster/kuberay-rayjob.yaml uses; other properties are kept as {} (names only).",
        ],
        "schema": trim(schema, jobs),
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.out}")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    schema = crd_schema(args.crd) if args.crd else extract_schema()
    errors = [e for job in rayjobs(documents(args.manifest)) for e in validate(job, schema)]
    print("\n".join(errors) or "valid")
    return 1 if errors else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    ex = sub.add_parser("extract", help="write the trimmed schema from a KubeRay CRD file")
    ex.add_argument("--crd", required=True, help="ray.io_rayjobs.yaml of a KubeRay checkout")
    ex.add_argument("--source", required=True, help="where the CRD came from (repository, tag, commit)")
    ex.add_argument("--manifest", default=str(MANIFEST))
    ex.add_argument("--out", default=str(EXTRACT))
    ck = sub.add_parser("check", help="validate the manifest's RayJob")
    ck.add_argument("--crd", help="a full CRD file (default: the committed extract)")
    ck.add_argument("--manifest", default=str(MANIFEST))
    args = p.parse_args(argv)
    return {"extract": cmd_extract, "check": cmd_check}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
