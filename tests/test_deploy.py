"""Deployment files: the Dockerfile (its configuration and build context; its steps run for
real by cluster/check_image_steps.py, opt-in), the Ray cluster launcher config against
Ray's own schema, the KubeRay RayJob manifest against KubeRay's CRD schema, and
`deepphy run` joining the cluster that RAY_ADDRESS names (as inside a RayJob)."""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
CLUSTER = ROOT / "cluster"


def _module(name: str):
    spec = importlib.util.spec_from_file_location(name, CLUSTER / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


image_steps = _module("check_image_steps")
kuberay = _module("kuberay_schema")


def _instructions():
    return image_steps.parse_dockerfile((ROOT / "Dockerfile").read_text())


def _locked_version(package: str) -> str:
    lock = tomllib.loads((ROOT / "uv.lock").read_text())
    return next(p["version"] for p in lock["package"] if p["name"] == package)


def _image_uid() -> int:
    """The uid the Dockerfile gives its user (`useradd --uid N`)."""
    runs = " ".join(i.args for i in _instructions() if i.name == "RUN")
    return int(re.search(r"useradd\b[^&]*--uid (\d+)", runs).group(1))


# ---------------------------------------------------------------- Dockerfile


def test_parse_dockerfile_joins_continuations_and_rejects_what_the_check_cannot_run():
    text = "# syntax comment\nFROM base\nRUN --mount=type=cache,target=/c a \\\n  # inside\n  && b\nENV A=1 B=\"x y\"\n"
    run = image_steps.parse_dockerfile(text)[1]
    assert (run.name, run.flags, run.args) == ("RUN", {"mount": "type=cache,target=/c"}, "a && b")
    assert image_steps.image_config(image_steps.parse_dockerfile(text)).env["B"] == "x y"
    with pytest.raises(ValueError, match="line 2: ADD"):
        image_steps.parse_dockerfile("FROM base\nADD x /y\n")


def test_image_config_is_what_ray_up_and_kuberay_need():
    config = image_steps.image_config(_instructions())
    assert _instructions()[0].args == image_steps.BASE_IMAGE  # the base the image check emulates
    assert config.user not in ("", "root", "0")
    # `ray up` places file mounts (the token) under the HOME of the image's config.
    assert config.env["HOME"] == f"/home/{config.user}"
    assert config.env["RAY_USAGE_STATS_ENABLED"] == "0" and config.env["RAY_AUTH_MODE"] == "token"
    assert config.env["PATH"].split(":")[0] == config.env["UV_PROJECT_ENVIRONMENT"] + "/bin"
    assert config.workdir == "/data"
    # `ray up` starts the container as `docker run IMAGE bash`: an ENTRYPOINT would swallow it
    # (parse_dockerfile rejects ENTRYPOINT, so only CMD can be set).
    assert json.loads(config.cmd)[0] == "deepphy"
    runs = [i.args for i in _instructions() if i.name == "RUN"]
    assert any("uv sync --frozen --no-dev" in r and "--no-install-project" not in r for r in runs)


def test_build_context_leaves_out_local_state(tmp_path):
    shutil.copy(ROOT / ".dockerignore", tmp_path)
    keep = ["pyproject.toml", "uv.lock", "README.md", "deepphy/cli.py", "deepphy/envs/phyre/templates/variants.json"]
    drop = [".venv/bin/python", ".git/HEAD", "runs/demo/attempts.jsonl", "deepphy/__pycache__/cli.cpython-311.pyc",
            "deepphy/envs/__pycache__/base.cpython-311.pyc", "tests/test_cli.py", ".pytest_cache/v/x",
            "deepphy/.cache/x", "cluster/ray-cluster.yaml", "deepphy.egg-info/PKG-INFO"]
    for rel in keep + drop:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x")
    assert set(image_steps.context_files(tmp_path)) == set(keep)


def test_every_copy_source_is_in_the_build_context():
    files = image_steps.context_files(ROOT)
    for ins in _instructions():
        if ins.name == "COPY":
            for source in shlex.split(ins.args)[:-1]:
                assert any(f == source or f.startswith(source + "/") for f in files), source
    assert not any(f.startswith((".venv/", ".git/", "runs/")) or "__pycache__" in f for f in files)


@pytest.mark.slow
@pytest.mark.timeout(3600)
@pytest.mark.skipif(os.environ.get("DEEPPHY_IMAGE_CHECK") != "1" or os.geteuid() != 0,
                    reason="opt-in (DEEPPHY_IMAGE_CHECK=1, root, network): builds a Debian root filesystem, 5-15 min")
def test_image_steps_run_for_real():
    workdir = tempfile.mkdtemp(prefix="deepphy-image-check-")
    result = subprocess.run([sys.executable, str(CLUSTER / "check_image_steps.py"), "--workdir", workdir],
                            capture_output=True, text=True, timeout=3600)
    assert result.returncode == 0, result.stdout[-5000:] + result.stderr[-5000:]
    facts = json.loads((Path(workdir) / "facts.json").read_text())
    assert set(facts["records"]) == {"iphyre", "phyre", "pooltool", "kinetix"}
    shutil.rmtree(workdir, ignore_errors=True)


# ---------------------------------------------------------------- Ray cluster launcher


def _ray_cluster() -> dict:
    return yaml.safe_load((CLUSTER / "ray-cluster.yaml").read_text())


def test_ray_cluster_config_passes_the_launchers_validation():
    import jsonschema
    import ray.autoscaler
    from ray.autoscaler._private.util import prepare_config, validate_config

    schema = json.loads((Path(ray.autoscaler.__file__).parent / "ray-schema.json").read_text())
    config = _ray_cluster()
    jsonschema.validate(config, schema)
    validate_config(prepare_config(copy.deepcopy(config)))  # what `ray up` does before touching a cloud
    bad = copy.deepcopy(config)
    bad["available_node_types"]["ray.worker.physics"]["min_worker"] = 1  # the validator is live
    with pytest.raises(jsonschema.ValidationError, match="min_worker"):
        jsonschema.validate(bad, schema)


def test_ray_cluster_puts_physics_on_workers_and_one_token_everywhere():
    from ray.autoscaler._private.util import prepare_config

    config = prepare_config(_ray_cluster())
    types = config["available_node_types"]
    head = types[config["head_node_type"]]
    workers = [t for name, t in types.items() if name != config["head_node_type"]]
    assert "physics" not in head["resources"] and head["resources"].get("CPU") == 0
    assert workers and all(t["resources"].get("physics", 0) >= 1 and t["min_workers"] >= 1 for t in workers)
    assert "--env RAY_AUTH_MODE=token" in config["docker"]["run_options"]
    # Ray's default token location, for the container user (file mounts expand ~ in the container).
    assert config["file_mounts"]["~/.ray"] == "~/.ray"
    assert any("--autoscaling-config=~/ray_bootstrap_config.yaml" in c for c in config["head_start_ray_commands"])
    assert any("$RAY_HEAD_IP:6379" in c for c in config["worker_start_ray_commands"])
    # Run directories live in the image's working directory, on a named volume.
    workdir = image_steps.image_config(_instructions()).workdir
    assert any(o.endswith(f":{workdir}") for o in config["docker"]["run_options"] if o.startswith("--volume"))


# ---------------------------------------------------------------- KubeRay


def _docs() -> list[dict]:
    return kuberay.documents(CLUSTER / "kuberay-rayjob.yaml")


def _job() -> dict:
    [job] = kuberay.rayjobs(_docs())
    return job


def _entrypoint():
    """The RayJob's entrypoint as parsed by deepphy's own CLI (so it must be a valid command)."""
    from deepphy.cli import build_parser

    words = shlex.split(_job()["spec"]["entrypoint"])
    assert words[:2] == ["deepphy", "run"]
    return build_parser().parse_args(words[1:])


def _rayjob_crd_schema() -> dict:
    """The full CRD when KUBERAY_CRD names a copy (e.g. a KubeRay checkout's
    ray-operator/config/crd/bases/ray.io_rayjobs.yaml), else the committed extract."""
    crd = os.environ.get("KUBERAY_CRD")
    return kuberay.crd_schema(crd) if crd else kuberay.extract_schema()


def test_rayjob_is_valid_under_kuberays_schema_and_typos_are_caught():
    schema = _rayjob_crd_schema()
    assert kuberay.validate(_job(), schema) == []
    typo, wrong_type = _job(), _job()
    typo["spec"]["rayClusterSpec"]["workerGroupSpecs"][0]["template"]["spec"]["containers"][0]["volumeMount"] = []
    wrong_type["spec"]["ttlSecondsAfterFinished"] = "600"
    assert kuberay.validate(typo, schema) == [
        "spec.rayClusterSpec.workerGroupSpecs[0].template.spec.containers[0].volumeMount: field not declared by the schema"]
    assert kuberay.validate(wrong_type, schema) == ["spec.ttlSecondsAfterFinished: '600' is not of type 'integer'"]


def test_schema_extract_covers_every_field_the_manifest_uses():
    """A field added to the manifest needs a re-extract (cluster/kuberay_schema.py extract),
    else the extract would know its name but not its type."""
    untyped = []

    def walk(value, schema, path):
        if not schema:
            untyped.append(path)
        elif isinstance(value, dict):
            for key, sub in value.items():
                walk(sub, schema.get("properties", {}).get(key, schema.get("additionalProperties")), f"{path}.{key}")
        elif isinstance(value, list):
            for i, item in enumerate(value):
                walk(item, schema.get("items"), f"{path}[{i}]")

    walk(_job()["spec"], kuberay.extract_schema()["properties"]["spec"], "spec")
    assert untyped == []


def test_rayjob_runs_deepphy_on_the_physics_group_and_keeps_runs_on_the_pvc():
    job, docs = _job(), _docs()
    spec, cluster = job["spec"], job["spec"]["rayClusterSpec"]
    head, [group] = cluster["headGroupSpec"], cluster["workerGroupSpecs"]
    # KubeRay's own limits on names (DNS-1035 label, 47 characters for a RayJob).
    assert re.fullmatch(r"[a-z]([-a-z0-9]*[a-z0-9])?", job["metadata"]["name"]) and len(job["metadata"]["name"]) <= 47
    # The entrypoint is a valid `deepphy run` that joins the job's cluster through RAY_ADDRESS.
    args = _entrypoint()
    assert args.address is None and args.env_resource
    # ... whose environment workers can only go to the worker group (KubeRay strips the
    # shell quotes of rayStartParams.resources, then reads JSON).
    resources = json.loads(group["rayStartParams"]["resources"].strip("'\"` ").replace('\\"', '"'))
    assert resources[args.env_resource] >= 1 and "resources" not in head["rayStartParams"]
    assert head["rayStartParams"]["num-cpus"] == "0"
    worker_cpus = int(group["template"]["spec"]["containers"][0]["resources"]["limits"]["cpu"])
    assert args.env_workers == group["replicas"] * worker_cpus
    assert group["minReplicas"] <= group["replicas"] <= group["maxReplicas"]
    # The run directory is on the head (the driver writes it), on the PVC of this file.
    [pvc] = [d for d in docs if d["kind"] == "PersistentVolumeClaim"]
    head_pod = head["template"]["spec"]
    volumes = {v["name"]: v for v in head_pod["volumes"]}
    mounts = [m for m in head_pod["containers"][0]["volumeMounts"]
              if volumes[m["name"]].get("persistentVolumeClaim", {}).get("claimName") == pvc["metadata"]["name"]]
    assert any(Path(args.out).is_relative_to(m["mountPath"]) for m in mounts)
    assert head_pod["securityContext"]["fsGroup"] == _image_uid()
    # One image everywhere, with the Ray of uv.lock; token auth; the cluster goes away.
    images = {c["image"] for pod in (head_pod, group["template"]["spec"]) for c in pod["containers"]}
    assert images == {_ray_cluster()["docker"]["image"]}
    assert cluster["rayVersion"] == _locked_version("ray")
    assert cluster["authOptions"]["mode"] == "token"
    assert spec["shutdownAfterJobFinishes"] is True and spec["ttlSecondsAfterFinished"] > 0


def test_pvc_is_shared_and_sized():
    [pvc] = [d for d in _docs() if d["kind"] == "PersistentVolumeClaim"]
    assert pvc["apiVersion"] == "v1" and re.fullmatch(r"[a-z0-9]([-a-z0-9]*[a-z0-9])?", pvc["metadata"]["name"])
    assert pvc["spec"]["accessModes"] == ["ReadWriteMany"]
    # Kubernetes' quantity syntax, as the CRD schema spells it for container resources.
    quantity = kuberay.extract_schema()["properties"]["spec"]["properties"]["rayClusterSpec"]["properties"][
        "headGroupSpec"]["properties"]["template"]["properties"]["spec"]["properties"]["containers"]["items"][
        "properties"]["resources"]["properties"]["requests"]["additionalProperties"]["pattern"]
    assert re.match(quantity, pvc["spec"]["resources"]["requests"]["storage"])
    assert set(pvc) == {"apiVersion", "kind", "metadata", "spec"}
    assert set(pvc["spec"]) <= {"accessModes", "resources", "storageClassName", "volumeMode"}


def test_results_pod_reads_the_same_claim_with_the_same_image():
    pod = yaml.safe_load((CLUSTER / "kuberay-results-pod.yaml").read_text())
    [pvc] = [d for d in _docs() if d["kind"] == "PersistentVolumeClaim"]
    assert (pod["apiVersion"], pod["kind"]) == ("v1", "Pod")
    [volume] = pod["spec"]["volumes"]
    [container] = pod["spec"]["containers"]
    assert volume["persistentVolumeClaim"]["claimName"] == pvc["metadata"]["name"]
    [mount] = container["volumeMounts"]
    assert mount["name"] == volume["name"] and mount["readOnly"] is True
    # The RayJob writes its run directories under the same path, so `deepphy report PATH` is the same.
    assert Path(_entrypoint().out).is_relative_to(mount["mountPath"])
    assert container["image"] == _ray_cluster()["docker"]["image"]
    assert pod["spec"]["securityContext"]["fsGroup"] == _image_uid()


# ---------------------------------------------------------------- RAY_ADDRESS


def _run_cli(args: list[str], env: dict[str, str], out: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "deepphy.cli", "run", "--env", "iphyre", "--limit", "1", "--runs", "1",
           "--max-attempts", "1", "--out", str(out), "--no-progress", *args]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("address_args", [[], ["--address", "auto"]], ids=["RAY_ADDRESS", "auto"])
def test_run_joins_the_cluster_named_by_ray_address(ray_cluster, tmp_path, address_args):
    """Inside a RayJob (or `ray job submit`) the driver gets RAY_ADDRESS and no --address."""
    import ray

    proc = _run_cli(address_args, {**os.environ, "RAY_ADDRESS": ray_cluster}, tmp_path / "run")
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    # The driver registered with this session's cluster, not with one of its own.
    assert proc.pid in {job["DriverPid"] for job in ray._private.state.jobs()}
    assert (tmp_path / "run" / "attempts.jsonl").read_text().count("\n") == 1


@pytest.mark.slow
def test_run_without_address_starts_its_own_cluster_even_if_ray_start_left_an_address(ray_cluster, tmp_path):
    """`ray start` records its address in <ray temp dir>/ray_current_cluster, which a bare
    ray.init() would join (and then refuse deepphy's num_cpus)."""
    import ray

    ray_tmp = tempfile.mkdtemp(prefix="dpa", dir="/tmp")  # short: Ray's socket paths
    try:
        (Path(ray_tmp) / "ray").mkdir()
        (Path(ray_tmp) / "ray" / "ray_current_cluster").write_text(ray_cluster)
        env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
        proc = _run_cli([], {**env, "RAY_TMPDIR": ray_tmp}, tmp_path / "run")
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
        assert proc.pid not in {job["DriverPid"] for job in ray._private.state.jobs()}
    finally:
        shutil.rmtree(ray_tmp, ignore_errors=True)
