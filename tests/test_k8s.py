"""deploy/k8s: every manifest valid against a current Kubernetes release's schemas (strict: no
unknown field), and its numbers agreeing with the service's (body size, deadline, drain, probes)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import kubernetes_validate
import pytest
import yaml

from service.settings import Settings

K8S = Path(__file__).resolve().parents[1] / "deploy" / "k8s"
KUBERNETES = "1.37.0"  # the newest release kubernetes-validate ships the schemas of, offline


def documents() -> list[dict[str, Any]]:
    return [doc for path in sorted(K8S.glob("*.yaml")) if path.name != "kustomization.yaml"
            for doc in yaml.safe_load_all(path.read_text()) if doc]


def kind(name: str) -> list[dict[str, Any]]:
    return [doc for doc in documents() if doc["kind"] == name]


@pytest.mark.parametrize("doc", documents(), ids=lambda d: f"{d['kind']}/{d['metadata']['name']}")
def test_manifest_is_valid_for_a_current_kubernetes(doc: dict[str, Any]) -> None:
    kubernetes_validate.validate(doc, KUBERNETES, strict=True)


def test_kustomization_lists_every_manifest() -> None:
    listed = yaml.safe_load((K8S / "kustomization.yaml").read_text())["resources"]
    assert sorted(listed) == sorted(p.name for p in K8S.glob("*.yaml") if p.name != "kustomization.yaml")


def test_kinds_and_a_bad_manifest_is_caught() -> None:
    assert {d["kind"] for d in documents()} == {"Deployment", "Service", "PodDisruptionBudget",
                                               "HorizontalPodAutoscaler", "Ingress"}
    broken = kind("Deployment")[0] | {"spec": {**kind("Deployment")[0]["spec"], "replicas": "two"}}
    with pytest.raises(kubernetes_validate.ValidationError):
        kubernetes_validate.validate(broken, KUBERNETES, strict=True)


def container() -> dict[str, Any]:
    (deployment,) = kind("Deployment")
    (only,) = deployment["spec"]["template"]["spec"]["containers"]
    return dict(only)


def env() -> dict[str, str]:
    return {e["name"]: e["value"] for e in container()["env"]}


def test_one_worker_per_pod_with_probes_on_the_service_routes() -> None:
    c = container()
    assert c["command"][c["command"].index("--workers") + 1] == "1"
    assert c["readinessProbe"]["httpGet"]["path"] == "/readyz"
    assert c["livenessProbe"]["httpGet"]["path"] == c["startupProbe"]["httpGet"]["path"] == "/livez"
    assert c["resources"]["requests"]["cpu"] == c["resources"]["limits"]["cpu"]  # the quota = the budget


def test_the_drain_fits_in_the_grace_period() -> None:
    spec = kind("Deployment")[0]["spec"]["template"]["spec"]
    pre_stop = int(container()["lifecycle"]["preStop"]["exec"]["command"][1])
    drain = float(env().get("QUADSYNTH_DRAIN_GRACE_S", Settings.drain_grace_s))
    assert spec["terminationGracePeriodSeconds"] > pre_stop + drain


def mebibytes(size: str) -> int:
    assert size.endswith("m"), size
    return int(size[:-1]) * 1024 * 1024


def test_ingress_limits_match_the_service() -> None:
    body = int(env().get("QUADSYNTH_MAX_BODY_BYTES", Settings.max_body_bytes))
    deadline = float(env().get("QUADSYNTH_DEADLINE_S", Settings.deadline_s))
    by_path = {ing["spec"]["rules"][0]["http"]["paths"][0]["path"]: ing["metadata"]["annotations"]
               for ing in kind("Ingress")}
    for notes in by_path.values():
        assert mebibytes(notes["nginx.ingress.kubernetes.io/proxy-body-size"]) == body
    rest, stream = by_path["/"], by_path["/v1/stream"]
    assert int(rest["nginx.ingress.kubernetes.io/proxy-read-timeout"]) > deadline
    # WebSocket sessions: far longer than a ping interval (20 s), so only a dead peer times out.
    assert int(stream["nginx.ingress.kubernetes.io/proxy-read-timeout"]) >= 3600
    (service,) = kind("Service")
    for ing in kind("Ingress"):
        backend = ing["spec"]["rules"][0]["http"]["paths"][0]["backend"]["service"]
        assert backend["name"] == service["metadata"]["name"]


def test_the_autoscaler_and_budget_target_the_deployment() -> None:
    (deployment,), (hpa,) = kind("Deployment"), kind("HorizontalPodAutoscaler")
    (pdb,) = kind("PodDisruptionBudget")
    assert hpa["spec"]["scaleTargetRef"]["name"] == deployment["metadata"]["name"]
    assert hpa["spec"]["minReplicas"] >= 2 and pdb["spec"]["maxUnavailable"] == 1  # one always serves
    labels = deployment["spec"]["template"]["metadata"]["labels"]
    assert pdb["spec"]["selector"]["matchLabels"].items() <= labels.items()
    assert kind("Service")[0]["spec"]["selector"].items() <= labels.items()
