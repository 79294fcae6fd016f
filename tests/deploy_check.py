#!/usr/bin/env python3
"""Static checks of Tessera's deployment files (everything under deploy/).

    python3 tests/deploy_check.py [ROOT] [--build-dir DIR] [--no-external] [--self-test]

Checks, without Docker, a cluster, Slurm or systemd running:
  - every YAML file under deploy/ parses (all documents of multi-document files);
  - Kubernetes objects have apiVersion, kind and metadata.name, the kustomization lists
    exactly the manifests beside it, workloads are internally consistent (selectors,
    volumes, probes, resources, known field names); the worker Deployment has replicas;
    the coordinator has a PersistentVolumeClaim under --state and --output, one replica,
    probes on its port (gRPC on a plaintext port, TCP or a command on a TLS one: the
    gRPC probe cannot do TLS) and a Service that selects it;
  - docker-compose.yml: a coordinator with volumes and a health check, workers with
    replicas, pointing at the coordinator's service and port;
  - the Dockerfile's build stage COPYs and RUNs deploy/setup.sh and installs nothing
    else by hand (or, if it lists packages itself, the same set as setup.sh), builds
    Release without tests and benchmarks, copies every CMake subdirectory the build
    needs, installs the three binaries CMake builds, and runs as a non-root user;
  - the Slurm script and the systemd units start binaries that exist with flags that
    exist (from the built binaries' --help when ROOT/build has them, else the
    documented flags), the values they need, and the hardening and stop settings;
  - security, in Compose, Kubernetes, systemd, Slurm and the image's default command:
    every coordinator listening off loopback has --tls-cert, --tls-key and --tokens,
    none has --insecure; every worker and CLI gets --tls-ca and --token-file (or their
    variables); those files come from Compose secrets (deploy/secrets/), read-only
    Kubernetes Secret volumes or systemd credentials; no file under deploy/ holds a PEM
    block, a token-like hex string, a --token flag or a TESSERA_TOKEN value, no manifest
    a Secret with data; deploy/secrets/ is git- and docker-ignored and made by
    deploy/make-secrets.sh;
  - where installed: bash -n, shellcheck, systemd-analyze verify, kubectl kustomize.

Prints one line per check and closes with "N passed, N failed, N skipped"; exits 1 if
any check failed. --self-test breaks copies of the files in known ways and expects the
checks to notice each one.
"""

import argparse
import copy
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

try:
    import yaml
except ImportError:  # python3-yaml is one of deploy/setup.sh's packages
    print("FAIL import yaml: python3-yaml is missing (bash deploy/setup.sh installs it)")
    print("0 passed, 1 failed")
    sys.exit(1)

# The programs, where CMake builds them, and the flags the deployment files may use
# (the documented command lines; replaced by a built binary's --help when there is one).
PROGRAMS = {
    "tessera-coordinator": {
        "dir": "coordinator",
        "flags": {"--listen", "--state", "--output", "--lease-ms", "--max-attempts",
                  "--port-file", "--tls-cert", "--tls-key", "--tls-client-ca", "--tokens",
                  "--insecure"},
        "required": {"--listen", "--state", "--output"},
    },
    "tessera-worker": {
        "dir": "worker",
        "flags": {"--coordinator", "--threads", "--name", "--cache", "--tls-ca",
                  "--tls-cert", "--tls-key", "--tls-server-name", "--token-file"},
        "required": {"--coordinator"},
    },
    "tessera": {"dir": "cli", "flags": None, "required": set()},
}
# First argument of the image's entry point -> program (deploy/docker-entrypoint.sh).
ENTRYPOINT_ALIASES = {
    "coordinator": "tessera-coordinator", "tessera-coordinator": "tessera-coordinator",
    "worker": "tessera-worker", "tessera-worker": "tessera-worker",
    "tessera": "tessera", "cli": "tessera",
}
# Packages the image's runtime stage may install by name although setup.sh does not:
# tini runs as PID 1 to forward SIGTERM and reap children.
RUNTIME_ONLY_PACKAGES = {"tini"}
# CMake subdirectories the image does not need (tests, benchmarks and fuzzers are off).
CMAKE_DIRS_NOT_BUILT = {"tests", "bench", "fuzz"}

# Field names Kubernetes accepts at the levels the manifests use: a misspelt field is
# silently dropped by a lenient apply, so it is an error here.
K8S_KEYS = {
    "container": {
        "name", "image", "imagePullPolicy", "command", "args", "workingDir", "ports",
        "env", "envFrom", "resources", "resizePolicy", "restartPolicy", "volumeMounts",
        "volumeDevices", "livenessProbe", "readinessProbe", "startupProbe", "lifecycle",
        "terminationMessagePath", "terminationMessagePolicy", "securityContext",
        "stdin", "stdinOnce", "tty"},
    "podspec": {
        "activeDeadlineSeconds", "affinity", "automountServiceAccountToken",
        "containers", "dnsConfig", "dnsPolicy", "enableServiceLinks",
        "ephemeralContainers", "hostAliases", "hostIPC", "hostNetwork", "hostPID",
        "hostUsers", "hostname", "imagePullSecrets", "initContainers", "nodeName",
        "nodeSelector", "os", "overhead", "preemptionPolicy", "priority",
        "priorityClassName", "readinessGates", "resourceClaims", "resources",
        "restartPolicy", "runtimeClassName", "schedulerName", "schedulingGates",
        "securityContext", "serviceAccount", "serviceAccountName", "setHostnameAsFQDN",
        "shareProcessNamespace", "subdomain", "terminationGracePeriodSeconds",
        "tolerations", "topologySpreadConstraints", "volumes"},
    "probe": {
        "exec", "httpGet", "tcpSocket", "grpc", "initialDelaySeconds", "timeoutSeconds",
        "periodSeconds", "successThreshold", "failureThreshold",
        "terminationGracePeriodSeconds"},
    "Deployment": {
        "replicas", "selector", "template", "strategy", "minReadySeconds",
        "revisionHistoryLimit", "paused", "progressDeadlineSeconds"},
    "StatefulSet": {
        "replicas", "selector", "template", "serviceName", "volumeClaimTemplates",
        "podManagementPolicy", "updateStrategy", "revisionHistoryLimit",
        "minReadySeconds", "persistentVolumeClaimRetentionPolicy", "ordinals"},
    "Service": {
        "ports", "selector", "clusterIP", "clusterIPs", "type", "externalIPs",
        "sessionAffinity", "sessionAffinityConfig", "loadBalancerIP",
        "loadBalancerSourceRanges", "loadBalancerClass", "externalName",
        "externalTrafficPolicy", "internalTrafficPolicy", "healthCheckNodePort",
        "publishNotReadyAddresses", "ipFamilies", "ipFamilyPolicy",
        "allocateLoadBalancerNodePorts", "trafficDistribution"},
}

SYSTEMD_REQUIRED = ["ExecStart", "Restart", "KillSignal", "TimeoutStopSec",
                    "EnvironmentFile", "NoNewPrivileges", "ProtectSystem"]


class CheckFailed(Exception):
    pass


class Skipped(Exception):
    pass


def fail(message):
    raise CheckFailed(message)


def expect(condition, message):
    if not condition:
        raise CheckFailed(message)


class Report:
    def __init__(self, quiet=False):
        self.passed = self.failed = self.skipped = 0
        self.failures = []
        self.messages = []
        self.quiet = quiet

    def run(self, name, fn, *args):
        try:
            note = fn(*args)
        except Skipped as e:
            self.skipped += 1
            self._print(f"SKIP {name}: {e}")
        except CheckFailed as e:
            self.failed += 1
            self.failures.append(name)
            self.messages.append(str(e))
            self._print(f"FAIL {name}: {e}")
        except Exception as e:  # a check that crashes on odd input is a failure
            self.failed += 1
            self.failures.append(name)
            self.messages.append(f"{type(e).__name__}: {e}")
            self._print(f"FAIL {name}: {type(e).__name__}: {e}")
        else:
            self.passed += 1
            self._print(f"PASS {name}" + (f" ({note})" if note else ""))

    def _print(self, line):
        if not self.quiet:
            print(line)


# ---------------------------------------------------------------------------------
# Reading the files
# ---------------------------------------------------------------------------------

def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def rel(root, path):
    return os.path.relpath(path, root)


def yaml_files(root):
    found = []
    for dirpath, dirnames, filenames in os.walk(os.path.join(root, "deploy")):
        dirnames.sort()
        for name in sorted(filenames):
            if name.endswith((".yaml", ".yml")):
                found.append(os.path.join(dirpath, name))
    return found


_YAML_CACHE = {}


def load_yaml(path):
    """The documents of a YAML file; parsed once per content (the self-test reads the
    same files dozens of times), a fresh copy each call."""
    text = read(path)
    if text not in _YAML_CACHE:
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        _YAML_CACHE[text] = [d for d in yaml.load_all(text, Loader=loader) if d is not None]
    return copy.deepcopy(_YAML_CACHE[text])


def setup_packages(root):
    """The PACKAGES=( ... ) array of deploy/setup.sh."""
    text = read(os.path.join(root, "deploy", "setup.sh"))
    m = re.search(r"^PACKAGES=\((.*?)^\)", text, re.S | re.M)
    if not m:
        fail("deploy/setup.sh has no PACKAGES=( ... ) array")
    words = []
    for line in m.group(1).splitlines():
        words += line.split("#", 1)[0].split()
    if not words:
        fail("deploy/setup.sh's PACKAGES array is empty")
    return set(words)


def logical_lines(text, comment_prefix="#"):
    """Joins backslash continuations; drops comment lines (also inside continuations,
    as Docker does). Returns (first line number, text) pairs."""
    out, buf, start = [], [], None
    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith(comment_prefix):
            continue
        if start is None:
            start = number
        if line.rstrip().endswith("\\"):
            buf.append(line.rstrip()[:-1])
            continue
        buf.append(line)
        joined = " ".join(part.strip() for part in buf).strip()
        if joined:
            out.append((start, joined))
        buf, start = [], None
    if buf:
        out.append((start, " ".join(part.strip() for part in buf).strip()))
    return out


def parse_dockerfile(text):
    """[(line, INSTRUCTION, arguments)]; the parser directives and comments dropped."""
    instructions = []
    for number, line in logical_lines(text):
        parts = line.split(None, 1)
        instructions.append((number, parts[0].upper(), parts[1] if len(parts) > 1 else ""))
    return instructions


def dockerfile_stages(instructions):
    """[{'name', 'base', 'line', 'body': [(line, instr, args)]}] in order."""
    stages = []
    for number, instr, args in instructions:
        if instr == "FROM":
            words = args.split()
            words = [w for w in words if not w.startswith("--")]
            name = words[2] if len(words) >= 3 and words[1].lower() == "as" else None
            stages.append({"name": name, "base": words[0], "line": number, "body": []})
        elif stages:
            stages[-1]["body"].append((number, instr, args))
    return stages


def resolve_args(text, instructions):
    """Replaces ${X} and $X by the default of a global ARG X=default."""
    defaults = {}
    for _, instr, args in instructions:
        if instr == "FROM":
            break
        if instr == "ARG" and "=" in args:
            k, v = args.split("=", 1)
            defaults[k.strip()] = v.strip().strip('"')
    return re.sub(r"\$\{?(\w+)\}?", lambda m: defaults.get(m.group(1), m.group(0)), text)


def shell_commands(run_args):
    """Splits a RUN's shell text into simple commands (at &&, ||, ;, |)."""
    return [c.strip() for c in re.split(r"&&|\|\||;|\|", run_args) if c.strip()]


def apt_installs(run_args):
    """Literal package names of every apt-get/apt install in a RUN, and whether one
    takes packages from elsewhere (xargs, a variable)."""
    packages, indirect = [], False
    for command in shell_commands(run_args):
        m = re.search(r"\bapt(?:-get)?\s+(?:\S+\s+)*?install\b(.*)", command)
        if not m:
            continue
        if re.search(r"\bxargs\b", command[:m.start()]) or "$" in m.group(1):
            indirect = True
        for word in m.group(1).split():
            if word.startswith("-") or "$" in word or word.startswith(("<", ">")):
                continue
            packages.append(word.split("=", 1)[0])
    return packages, indirect


def copy_sources(args):
    """(sources, destination, from_stage) of a COPY/ADD."""
    words = args.split()
    from_stage = None
    plain = []
    for w in words:
        if w.startswith("--from="):
            from_stage = w.split("=", 1)[1]
        elif not w.startswith("--"):
            plain.append(w)
    if args.strip().startswith("["):
        plain = json.loads(args[args.index("["):])
    return plain[:-1], plain[-1] if plain else "", from_stage


def top_level_subdirectories(root):
    """add_subdirectory() calls of the top CMakeLists.txt, with the if() they sit in."""
    text = read(os.path.join(root, "CMakeLists.txt"))
    dirs, conditions = [], []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        m = re.match(r"(if|elseif|else|endif)\s*\((.*)\)", line, re.I)
        if m:
            word = m.group(1).lower()
            if word == "if":
                conditions.append(m.group(2))
            elif word == "endif":
                conditions.pop()
            continue
        m = re.match(r"add_subdirectory\s*\(\s*([^\s)]+)", line, re.I)
        if m:
            dirs.append((m.group(1), " and ".join(conditions)))
    return dirs


# ---------------------------------------------------------------------------------
# Flags of the programs
# ---------------------------------------------------------------------------------

FLAG_RE = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
# Flags that take no value.
SWITCHES = {"--insecure", "--init", "--verbose"}


def known_flags(root, build_dir):
    """program -> (flags, where they came from)."""
    result = {}
    for program, info in PROGRAMS.items():
        if info["flags"] is None:
            continue
        binary = os.path.join(build_dir, info["dir"], program)
        source = "documented"
        flags = set(info["flags"])
        if os.access(binary, os.X_OK):
            try:
                out = subprocess.run([binary, "--help"], capture_output=True, text=True,
                                     timeout=30)
                helped = set(FLAG_RE.findall(out.stdout + out.stderr)) - {"--help"}
                if out.returncode == 0 and helped:
                    shown = rel(root, binary)
                    shown = binary if shown.startswith("..") else shown
                    flags, source = helped, f"{shown} --help"
            except (OSError, subprocess.TimeoutExpired):
                pass
        result[program] = (flags, source)
    return result


def check_invocation(program, words, flags, where):
    """words: the arguments after the program. Flags must exist, take a value, and the
    required ones must be there."""
    allowed, source = flags[program]
    used = []
    i = 0
    while i < len(words):
        w = words[i]
        if FLAG_RE.fullmatch(w.split("=", 1)[0]):
            name = w.split("=", 1)[0]
            expect(name in allowed,
                   f"{where}: {program} has no flag {name} (flags from {source}: "
                   f"{' '.join(sorted(allowed))})")
            if "=" not in w and name not in SWITCHES:
                expect(i + 1 < len(words) and not words[i + 1].startswith("--"),
                       f"{where}: {name} has no value")
                i += 1
            used.append(name)
        i += 1
    missing = PROGRAMS[program]["required"] - set(used)
    expect(not missing, f"{where}: {program} is started without {' '.join(sorted(missing))}")
    return used


def flag_value(words, flag):
    for i, w in enumerate(words):
        if w == flag and i + 1 < len(words):
            return words[i + 1]
        if w.startswith(flag + "="):
            return w.split("=", 1)[1]
    return None


def program_of(argv):
    """(program, its arguments) for an argv the image's entry point receives."""
    if not argv:
        return None, []
    head = os.path.basename(str(argv[0]))
    return ENTRYPOINT_ALIASES.get(head), [str(a) for a in argv[1:]]


# ---------------------------------------------------------------------------------
# YAML
# ---------------------------------------------------------------------------------

def check_yaml_parses(path):
    try:
        docs = load_yaml(path)
    except yaml.YAMLError as e:
        fail(str(e).replace("\n", " "))
    expect(docs, "no documents")
    for d in docs:
        expect(isinstance(d, dict), f"a document is a {type(d).__name__}, not a mapping")
    return f"{len(docs)} document{'s' if len(docs) != 1 else ''}"


def kubernetes_objects(root):
    """[(file, document)] of every manifest in deploy/kubernetes but the kustomization."""
    folder = os.path.join(root, "deploy", "kubernetes")
    objects = []
    for path in yaml_files(root):
        if os.path.dirname(path) != folder or os.path.basename(path).startswith("kustomization"):
            continue
        for doc in load_yaml(path):
            objects.append((rel(root, path), doc))
    return objects


def check_k8s_identity(root):
    objects = kubernetes_objects(root)
    expect(objects, "deploy/kubernetes has no manifests")
    names = set()
    for path, doc in objects:
        for key in ("apiVersion", "kind"):
            expect(isinstance(doc.get(key), str) and doc[key], f"{path}: an object without {key}")
        name = (doc.get("metadata") or {}).get("name")
        expect(isinstance(name, str) and name, f"{path}: a {doc['kind']} without metadata.name")
        expect(re.fullmatch(r"[a-z0-9]([-a-z0-9]*[a-z0-9])?", name),
               f"{path}: {doc['kind']} name {name!r} is not a DNS label")
        key = (doc["kind"], name)
        expect(key not in names, f"{path}: {doc['kind']}/{name} defined twice")
        names.add(key)
    return f"{len(objects)} objects"


def check_kustomization(root):
    folder = os.path.join(root, "deploy", "kubernetes")
    path = os.path.join(folder, "kustomization.yaml")
    expect(os.path.exists(path), "deploy/kubernetes/kustomization.yaml is missing")
    k = load_yaml(path)[0]
    expect(k.get("kind") == "Kustomization", "kustomization.yaml: kind is not Kustomization")
    resources = k.get("resources") or []
    expect(resources, "kustomization.yaml lists no resources")
    for r in resources:
        expect(os.path.exists(os.path.join(folder, r)), f"kustomization.yaml lists missing {r}")
    manifests = sorted(os.path.basename(p) for p in yaml_files(root)
                       if os.path.dirname(p) == folder
                       and not os.path.basename(p).startswith("kustomization"))
    unlisted = set(manifests) - set(resources)
    expect(not unlisted, f"kustomization.yaml does not list {' '.join(sorted(unlisted))}")
    return f"{len(resources)} resources"


def workloads(root):
    return [(p, d) for p, d in kubernetes_objects(root)
            if d.get("kind") in ("Deployment", "StatefulSet")]


def check_known_keys(where, mapping, level):
    unknown = set(mapping or {}) - K8S_KEYS[level]
    expect(not unknown, f"{where}: unknown field(s) {' '.join(sorted(unknown))}")


def check_k8s_workload_shape(root, flags):
    """Selectors, volumes, resources, field names and programs of every workload."""
    found = workloads(root)
    expect(found, "no Deployment or StatefulSet")
    for path, d in found:
        where = f"{path} {d['kind']}/{d['metadata']['name']}"
        spec = d.get("spec") or {}
        check_known_keys(where + " spec", spec, d["kind"])
        template = spec.get("template") or {}
        labels = (template.get("metadata") or {}).get("labels") or {}
        match = ((spec.get("selector") or {}).get("matchLabels")) or {}
        expect(match, f"{where}: no spec.selector.matchLabels")
        expect(all(labels.get(k) == v for k, v in match.items()),
               f"{where}: selector {match} does not select the pod labels {labels}")
        pod = template.get("spec") or {}
        check_known_keys(where + " pod spec", pod, "podspec")
        containers = pod.get("containers") or []
        expect(containers, f"{where}: no containers")
        volumes = {v.get("name") for v in pod.get("volumes") or []}
        volumes |= {(c.get("metadata") or {}).get("name")
                    for c in spec.get("volumeClaimTemplates") or []}
        for c in containers:
            cw = f"{where} container {c.get('name')}"
            check_known_keys(cw, c, "container")
            expect(c.get("image"), f"{cw}: no image")
            for probe in ("livenessProbe", "readinessProbe", "startupProbe"):
                if probe in c:
                    check_known_keys(f"{cw} {probe}", c[probe], "probe")
            res = c.get("resources") or {}
            for kind in ("requests", "limits"):
                for r in ("cpu", "memory"):
                    expect(r in (res.get(kind) or {}), f"{cw}: no resources.{kind}.{r}")
            for m in c.get("volumeMounts") or []:
                expect(m.get("name") in volumes,
                       f"{cw}: mounts volume {m.get('name')!r} that the pod does not define")
            program, words = program_of((c.get("command") or []) + (c.get("args") or []))
            expect(program in ("tessera-coordinator", "tessera-worker"),
                   f"{cw}: does not start the coordinator or a worker")
            check_invocation(program, words, flags, cw)
    return f"{len(found)} workloads"


def pod_program(d):
    for c in ((d.get("spec") or {}).get("template") or {}).get("spec", {}).get("containers") or []:
        program, words = program_of((c.get("command") or []) + (c.get("args") or []))
        if program:
            return program, words, c
    return None, [], None


def find_workload(root, program):
    matches = [(p, d) for p, d in workloads(root) if pod_program(d)[0] == program]
    expect(len(matches) == 1,
           f"expected one workload running {program}, found {len(matches)}")
    return matches[0]


def listen_port(words):
    listen = flag_value(words, "--listen") or ""
    m = re.search(r":(\d+)$", listen)
    expect(m, f"--listen {listen!r} has no :PORT")
    return int(m.group(1))


def mount_for(path, mounts):
    """The volumeMount whose mountPath contains path (longest match)."""
    best = None
    for m in mounts:
        mp = m.get("mountPath", "").rstrip("/")
        if path == mp or path.startswith(mp + "/"):
            if best is None or len(mp) > len(best.get("mountPath", "")):
                best = m
    return best


def check_k8s_coordinator(root):
    path, d = find_workload(root, "tessera-coordinator")
    where = f"{path} {d['kind']}/{d['metadata']['name']}"
    spec = d["spec"]
    expect(spec.get("replicas", 1) == 1,
           f"{where}: replicas must be 1 (one SQLite database, one coordinator)")
    _, words, c = pod_program(d)
    pod = spec["template"]["spec"]
    # --state and --output must live on persistent volumes.
    claims = {(t.get("metadata") or {}).get("name") for t in spec.get("volumeClaimTemplates") or []}
    pvc_objects = {doc["metadata"]["name"] for _, doc in kubernetes_objects(root)
                   if doc.get("kind") == "PersistentVolumeClaim"}
    for v in pod.get("volumes") or []:
        claim = (v.get("persistentVolumeClaim") or {}).get("claimName")
        if claim:
            expect(claim in pvc_objects,
                   f"{where}: volume {v['name']} uses PersistentVolumeClaim {claim}, "
                   "which no manifest defines")
            claims.add(v["name"])
    expect(claims, f"{where}: no PersistentVolumeClaim (volumeClaimTemplates or a claim)")
    for flag in ("--state", "--output"):
        value = flag_value(words, flag)
        m = mount_for(value, c.get("volumeMounts") or [])
        expect(m is not None, f"{where}: {flag} {value} is on no volume")
        expect(m["name"] in claims,
               f"{where}: {flag} {value} is on volume {m['name']}, not a PersistentVolumeClaim")
    # Probes on the listening port: gRPC health checks on a plaintext port; on a TLS port
    # (Kubernetes' gRPC probe cannot do TLS) a TCP connect or a command.
    port = listen_port(words)
    container_ports = {p.get("containerPort") for p in c.get("ports") or []}
    expect(port in container_ports, f"{where}: --listen port {port} is not a containerPort")
    named_ports = {p.get("name"): p.get("containerPort") for p in c.get("ports") or []}
    tls = "--tls-cert" in words
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        spec_ = c.get(probe)
        if spec_ is None:
            expect(probe == "startupProbe", f"{where}: no {probe}")
            continue
        if tls:
            expect("grpc" not in spec_,
                   f"{where}: {probe} is a gRPC probe, which cannot speak TLS to a coordinator "
                   "serving --tls-cert (use tcpSocket or exec)")
            kind = "tcpSocket" if "tcpSocket" in spec_ else "exec" if "exec" in spec_ else None
            expect(kind, f"{where}: {probe} is neither tcpSocket nor exec")
            if kind == "exec":
                continue
            checked = spec_[kind].get("port")
        else:
            expect("grpc" in spec_, f"{where}: no gRPC {probe}")
            checked = spec_["grpc"].get("port")
        checked = named_ports.get(checked, checked)
        expect(checked == port,
               f"{where}: {probe} checks port {checked}, the coordinator listens on {port}")
    # The Service.
    labels = spec["template"]["metadata"]["labels"]
    services = [doc for _, doc in kubernetes_objects(root) if doc.get("kind") == "Service"
                and doc.get("spec", {}).get("selector")
                and all(labels.get(k) == v for k, v in doc["spec"]["selector"].items())]
    expect(len(services) == 1,
           f"expected one Service selecting the coordinator, found {len(services)}")
    svc = services[0]
    check_known_keys(f"Service/{svc['metadata']['name']} spec", svc["spec"], "Service")
    expect(svc["spec"].get("type", "ClusterIP") == "ClusterIP",
           f"Service/{svc['metadata']['name']} is {svc['spec'].get('type')}, not ClusterIP")
    named = {p.get("name"): p.get("containerPort") for p in c.get("ports") or []}
    targets = []
    for p in svc["spec"].get("ports") or []:
        target = p.get("targetPort", p.get("port"))
        targets.append(named.get(target, target))
    expect(port in targets, f"Service/{svc['metadata']['name']} does not forward to port {port}")
    if d["kind"] == "StatefulSet":
        expect(spec.get("serviceName"), f"{where}: no serviceName")
    return f"{d['kind']}, claims {' '.join(sorted(claims))}, Service {svc['metadata']['name']}"


def check_k8s_worker(root):
    path, d = find_workload(root, "tessera-worker")
    where = f"{path} {d['kind']}/{d['metadata']['name']}"
    expect(d["kind"] == "Deployment", f"{where}: workers should be a Deployment")
    replicas = d["spec"].get("replicas")
    expect(isinstance(replicas, int) and replicas >= 1, f"{where}: no replicas (the farm size)")
    pod = d["spec"]["template"]["spec"]
    grace = pod.get("terminationGracePeriodSeconds", 30)
    expect(grace >= 120, f"{where}: terminationGracePeriodSeconds {grace} leaves no time to "
                         "finish a tile after SIGTERM")
    _, words, c = pod_program(d)
    # --coordinator names the coordinator's Service and port.
    _, coord = find_workload(root, "tessera-coordinator")
    port = listen_port(pod_program(coord)[1])
    services = {doc["metadata"]["name"]: doc for _, doc in kubernetes_objects(root)
                if doc.get("kind") == "Service"}
    target = flag_value(words, "--coordinator") or ""
    host, _, tport = target.rpartition(":")
    host = host.split(".")[0]
    expect(host in services, f"{where}: --coordinator {target}: no Service named {host}")
    expect(any(str(p.get("port")) == tport for p in services[host]["spec"].get("ports") or []),
           f"{where}: --coordinator {target}: Service {host} has no port {tport}")
    # --threads matches the CPU the pod gets.
    threads = flag_value(words, "--threads")
    cpu = str(c["resources"]["requests"]["cpu"])
    if threads and threads.isdigit() and cpu.isdigit():
        expect(threads == cpu, f"{where}: --threads {threads} but requests.cpu {cpu}")
    return f"replicas {replicas}, grace {grace}s, coordinator {target} (port {port})"


# ---------------------------------------------------------------------------------
# Docker Compose
# ---------------------------------------------------------------------------------

def compose_services(root):
    path = os.path.join(root, "deploy", "docker-compose.yml")
    expect(os.path.exists(path), "deploy/docker-compose.yml is missing")
    doc = load_yaml(path)[0]
    services = doc.get("services") or {}
    expect(services, "docker-compose.yml has no services")
    return doc, services


def compose_argv(svc):
    argv = svc.get("command") or []
    if isinstance(argv, str):
        argv = shlex.split(argv)
    return [str(a) for a in argv]


def check_compose(root, flags):
    doc, services = compose_services(root)
    by_program = {}
    for name, svc in services.items():
        program, words = program_of(compose_argv(svc))
        if program in ("tessera-coordinator", "tessera-worker"):
            check_invocation(program, words, flags, f"docker-compose.yml service {name}")
            by_program.setdefault(program, []).append((name, svc, words))
        for net in svc.get("networks") or []:
            expect(net in (doc.get("networks") or {}),
                   f"service {name} uses network {net}, which is not declared")
        for vol in svc.get("volumes") or []:
            source = str(vol).split(":", 1)[0]
            if not source.startswith((".", "/", "$", "~")):
                expect(source in (doc.get("volumes") or {}),
                       f"service {name} uses volume {source}, which is not declared")
        build = svc.get("build")
        if isinstance(build, dict):
            context = os.path.normpath(os.path.join(root, "deploy", build.get("context", ".")))
            dockerfile = os.path.join(context, build.get("dockerfile", "Dockerfile"))
            expect(os.path.exists(dockerfile), f"service {name} builds from missing {dockerfile}")
    expect(len(by_program.get("tessera-coordinator", [])) == 1,
           "docker-compose.yml needs exactly one coordinator service")
    expect(by_program.get("tessera-worker"), "docker-compose.yml has no worker service")
    cname, coord, cwords = by_program["tessera-coordinator"][0]
    port = listen_port(cwords)
    for flag in ("--state", "--output"):
        value = flag_value(cwords, flag)
        targets = [str(v).split(":")[1] for v in coord.get("volumes") or [] if ":" in str(v)]
        expect(any(value == t or value.startswith(t.rstrip("/") + "/") for t in targets),
               f"coordinator {flag} {value} is not on a volume")
    test = (coord.get("healthcheck") or {}).get("test")
    expect(test, f"service {cname} has no healthcheck")
    expect(str(port) in " ".join(map(str, test if isinstance(test, list) else [test])),
           f"service {cname}'s healthcheck does not check port {port}")
    for wname, wsvc, words in by_program["tessera-worker"]:
        replicas = (wsvc.get("deploy") or {}).get("replicas", wsvc.get("scale"))
        expect(replicas is not None, f"service {wname} has neither deploy.replicas nor scale")
        target = flag_value(words, "--coordinator") or ""
        expect(target == f"{cname}:{port}",
               f"service {wname}: --coordinator {target}, the coordinator is {cname}:{port}")
    workers = " ".join(n for n, _, _ in by_program["tessera-worker"])
    return f"coordinator {cname}:{port}, workers {workers}"


# ---------------------------------------------------------------------------------
# Dockerfile
# ---------------------------------------------------------------------------------

def dockerfile(root):
    path = os.path.join(root, "deploy", "Dockerfile")
    expect(os.path.exists(path), "deploy/Dockerfile is missing")
    instructions = parse_dockerfile(read(path))
    stages = dockerfile_stages(instructions)
    expect(len(stages) >= 2, "the Dockerfile is not multi-stage")
    return instructions, stages


CMAKE_COMMAND = re.compile(r"(?:^|[;&|(]\s*)cmake\s")  # cmake run, not a package named cmake


def build_stage(stages):
    for s in stages:
        if any(i == "RUN" and CMAKE_COMMAND.search(a) for _, i, a in s["body"]):
            return s
    fail("no stage runs cmake")


def check_docker_packages(root):
    """The build stage installs exactly deploy/setup.sh's packages."""
    instructions, stages = dockerfile(root)
    wanted = setup_packages(root)
    stage = build_stage(stages)
    # Where does deploy/setup.sh land, and is it run?
    copied_to = None
    ran = False
    literal, runs = [], []
    for number, instr, args in stage["body"]:
        if instr in ("COPY", "ADD"):
            sources, dest, from_stage = copy_sources(args)
            if from_stage is None and "deploy/setup.sh" in [s.lstrip("./") for s in sources]:
                copied_to = dest.rstrip("/") + "/setup.sh" if dest.endswith("/") else dest
        elif instr == "RUN":
            runs.append(args)
            if copied_to and re.search(r"(^|[\s;&|])(bash\s+|sh\s+)?" + re.escape(copied_to)
                                       + r"(\s|$|;|&)", args):
                ran = True
            pkgs, _ = apt_installs(args)
            literal += pkgs
        if instr == "RUN" and CMAKE_COMMAND.search(args):
            break  # packages installed after the build do not count
    if copied_to or ran:
        expect(copied_to, "the build stage runs setup.sh without COPYing deploy/setup.sh")
        expect(ran, f"the build stage COPYs deploy/setup.sh to {copied_to} but never RUNs it "
                    "before cmake")
        extra = set(literal) - wanted
        expect(not literal, "the build stage installs packages by hand besides setup.sh: "
                            + " ".join(sorted(set(literal))) +
                            (f" (not in setup.sh: {' '.join(sorted(extra))})" if extra else ""))
        note = f"runs setup.sh ({len(wanted)} packages)"
    else:
        got = set(literal)
        expect(got, "the build stage neither runs deploy/setup.sh nor installs packages")
        missing, extra = wanted - got, got - wanted
        expect(not missing and not extra,
               "build stage packages differ from deploy/setup.sh: "
               + (f"missing {' '.join(sorted(missing))}" if missing else "")
               + ("; " if missing and extra else "")
               + (f"extra {' '.join(sorted(extra))}" if extra else ""))
        note = f"lists the same {len(wanted)} packages as setup.sh"
    # Other stages install only derived lists, setup.sh packages or the runtime extras.
    for s in stages:
        if s is stage:
            continue
        for number, instr, args in s["body"]:
            if instr == "RUN":
                pkgs, _ = apt_installs(args)
                unknown = set(pkgs) - wanted - RUNTIME_ONLY_PACKAGES
                extras = " ".join(sorted(RUNTIME_ONLY_PACKAGES))
                expect(not unknown, f"Dockerfile line {number}: stage {s['name']} installs "
                                    f"{' '.join(sorted(unknown))}, in neither setup.sh nor "
                                    f"the runtime extras ({extras})")
    return note


def check_docker_build(root):
    """Debian 12, Release without tests/bench, every needed source COPYed, binaries."""
    instructions, stages = dockerfile(root)
    for s in stages:
        base = resolve_args(s["base"], instructions)
        expect(re.fullmatch(r"(docker\.io/)?(library/)?debian:(bookworm|12)([-.\w]*)(@sha256:\w+)?",
                            base) or base in {t["name"] for t in stages if t["name"]},
               f"Dockerfile line {s['line']}: stage base {base} is not Debian 12 (bookworm)")
    stage = build_stage(stages)
    cmake = " ".join(a for _, i, a in stage["body"] if i == "RUN" and CMAKE_COMMAND.search(a))
    for option in ("-DCMAKE_BUILD_TYPE=Release", "-DTESSERA_BUILD_TESTS=OFF",
                   "-DTESSERA_BUILD_BENCH=OFF"):
        expect(option in cmake, f"the build does not pass {option}")
    # Every source folder the configure step reads is in the image.
    copied = set()
    for _, instr, args in stage["body"]:
        if instr in ("COPY", "ADD"):
            sources, _, from_stage = copy_sources(args)
            if from_stage is None:
                copied |= {os.path.normpath(s) for s in sources}
    for st in stages:
        for number, instr, args in st["body"]:
            if instr in ("COPY", "ADD") and copy_sources(args)[2] is None:
                for s in copy_sources(args)[0]:
                    expect(os.path.exists(os.path.join(root, s)),
                           f"Dockerfile line {number} COPYs missing {s}")
    if "." not in copied:
        expect("CMakeLists.txt" in copied, "the build stage does not COPY CMakeLists.txt")
        for d, condition in top_level_subdirectories(root):
            if d in CMAKE_DIRS_NOT_BUILT:
                continue
            expect(d in copied, f"CMakeLists.txt adds subdirectory {d}"
                                f"{' (if ' + condition + ')' if condition else ''}, "
                                "which the build stage does not COPY")
    # The three programs: CMake targets that exist, copied from where CMake puts them.
    text = read(os.path.join(root, "deploy", "Dockerfile"))
    for program, info in PROGRAMS.items():
        cmakelists = os.path.join(root, info["dir"], "CMakeLists.txt")
        expect(os.path.exists(cmakelists) and
               re.search(r"add_executable\s*\(\s*" + re.escape(program) + r"[\s)]",
                         read(cmakelists)),
               f"{info['dir']}/CMakeLists.txt defines no executable {program}")
        expect(f"build/{info['dir']}/{program}" in text,
               f"the Dockerfile does not take build/{info['dir']}/{program}")
    # Runtime: a non-root user and an entry point.
    final = stages[-1]
    users = [a.strip() for _, i, a in final["body"] if i == "USER"]
    expect(users, "the final stage sets no USER")
    expect(users[-1].split(":")[0] not in ("root", "0"), f"the final stage runs as {users[-1]}")
    expect(any(i == "ENTRYPOINT" for _, i, _ in final["body"]), "the final stage has no ENTRYPOINT")
    return f"{len(stages)} stages, {len(copied)} COPY sources"


def check_entrypoint(root):
    """deploy/docker-entrypoint.sh dispatches coordinator/worker/tessera to the binaries."""
    instructions, stages = dockerfile(root)
    entry = [a for _, i, a in stages[-1]["body"] if i == "ENTRYPOINT"][-1]
    path = os.path.join(root, "deploy", "docker-entrypoint.sh")
    if "entrypoint" not in entry:
        raise Skipped("the image has no entry-point script")
    text = read(path)
    for word, program in (("coordinator", "tessera-coordinator"), ("worker", "tessera-worker"),
                          ("tessera", "tessera")):
        arm = r"[\w \t|\"'*.-]*"  # a case pattern: words, |, quotes, globs
        m = re.search(r"^[ \t]*(" + arm + r"(?<![\w-])" + word + r"(?![\w-])" + arm
                      + r")\)[ \t]*\n(.*?);;", text, re.M | re.S)
        expect(m and re.search(r"exec\s+\S*/" + re.escape(program) + r"(?![\w-])", m.group(2)),
               f"docker-entrypoint.sh does not exec {program} for '{word}'")
    return None


# ---------------------------------------------------------------------------------
# Slurm and systemd: shell command lines
# ---------------------------------------------------------------------------------

def variables_naming(text, program):
    """Shell variables whose value is (derived from) the path of program."""
    assignments = re.findall(r"(?:^|[\s;(])(\w+)=(\"[^\"]*\"|'[^']*'|\S+)", text, re.M)
    names = set()
    changed = True
    while changed:
        changed = False
        for name, value in assignments:
            if name in names:
                continue
            refs = set(re.findall(r"\$\{?(\w+)", value))
            if re.search(r"(^|[/\s\"'])" + re.escape(program) + r"\b", value) or refs & names:
                names.add(name)
                changed = True
    return names


def invocations_in_shell(text, program, must_contain=None):
    """Argument words after each reference to program (by name or a variable naming
    it) on logical lines (optionally only those containing must_contain)."""
    names = variables_naming(text, program)
    ref = re.compile(r"\"?\$\{?(?:" + "|".join(map(re.escape, sorted(names)))
                     + r")(?!\w)\}?\"?") if names else None
    found = []
    for number, line in logical_lines(text):
        if must_contain and not re.search(must_contain, line):
            continue
        candidates = []
        if ref:
            candidates += [m.end() for m in ref.finditer(line)]
        candidates += [m.end() for m in re.finditer(r"(?<![\w=-])(\S*/)?" + re.escape(program)
                                                     + r"(?![\w-])", line)]
        for end in sorted(candidates)[:1]:
            rest = re.split(r"'|;|&&|\|\||\|", line[end:])[0]
            words = shlex.split(rest.replace("$", "_"), posix=True) if rest.strip() else []
            found.append((number, words))
    return found


def check_sbatch(root, flags, external):
    path = os.path.join(root, "deploy", "slurm", "tessera-workers.sbatch")
    expect(os.path.exists(path), "deploy/slurm/tessera-workers.sbatch is missing")
    text = read(path)
    expect(text.startswith("#!"), "no #! line")
    if external and shutil.which("bash"):
        out = subprocess.run(["bash", "-n", path], capture_output=True, text=True)
        expect(out.returncode == 0, "bash -n: " + out.stderr.strip())
    directives = re.findall(r"^#SBATCH\s+(\S+)", text, re.M)
    expect(directives, "no #SBATCH directives")
    first_command = next((n for n, l in logical_lines(text)), None)
    last_directive = max(n for n, l in enumerate(text.splitlines(), 1) if l.startswith("#SBATCH"))
    expect(first_command is None or last_directive < first_command,
           "#SBATCH directives after the first command are ignored by sbatch")
    calls = invocations_in_shell(text, "tessera-worker", must_contain=r"\bsrun\b")
    expect(calls, "no srun line starts tessera-worker")
    for number, words in calls:
        check_invocation("tessera-worker", words, flags, f"line {number}")
        expect("--threads" in words, f"line {number}: the worker gets no --threads")
    # --threads must come from SLURM_CPUS_PER_TASK (directly or through a variable).
    threads_source = [line for _, line in logical_lines(text)
                      if "--threads" in line and "srun" in line]
    chain = {"SLURM_CPUS_PER_TASK"}
    for name, value in re.findall(r"(?:^|[\s;])(\w+)=(\"[^\"]*\"|\S+)", text, re.M):
        if set(re.findall(r"\$\{?(\w+)", value)) & chain:
            chain.add(name)
    expect(any(re.search(r"--threads\s+\"?\$\{?(" + "|".join(chain) + r")\b", l)
               for l in threads_source),
           "--threads does not come from SLURM_CPUS_PER_TASK")
    expect(re.search(r"\$\{?1\b", text) or re.search(r"TESSERA_COORDINATOR", text),
           "the coordinator address comes from neither an argument nor TESSERA_COORDINATOR")
    return f"{len(calls)} srun worker line(s), #SBATCH {' '.join(directives)}"


def parse_unit(text):
    """{section: [(key, value)]} with continuation lines joined."""
    sections, current = {}, None
    for _, line in logical_lines(text, comment_prefix="#"):
        if line.startswith(";"):
            continue
        m = re.fullmatch(r"\[(\w+)\]", line)
        if m:
            current = sections.setdefault(m.group(1), [])
            continue
        expect(current is not None and "=" in line, f"not a unit line: {line!r}")
        key, value = line.split("=", 1)
        current.append((key.strip(), value.strip()))
    return sections


def check_systemd_unit(root, name, flags):
    path = os.path.join(root, "deploy", "systemd", name)
    expect(os.path.exists(path), f"deploy/systemd/{name} is missing")
    unit = parse_unit(read(path))
    for section in ("Unit", "Service", "Install"):
        expect(section in unit, f"no [{section}] section")
    service = unit["Service"]
    keys = {k for k, _ in service}
    for key in SYSTEMD_REQUIRED:
        expect(key in keys, f"no {key}=")
    get = lambda k: [v for kk, v in service if kk == k]
    expect(get("Restart")[-1] == "on-failure", f"Restart={get('Restart')[-1]}, not on-failure")
    expect(get("KillSignal")[-1] in ("SIGTERM", "TERM", "15"), "KillSignal is not SIGTERM")
    expect("DynamicUser" in keys or "User" in keys, "neither DynamicUser= nor User=")
    if "User" in keys and "DynamicUser" not in keys:
        expect(get("User")[-1] not in ("root", "0"), "runs as root")
    program = "tessera-worker" if "worker" in name else "tessera-coordinator"
    if program == "tessera-coordinator":
        expect("StateDirectory" in keys, "no StateDirectory=")
    else:
        expect("%i" in name or "@" in name, "the worker unit is not a template (name@.service)")
        expect(any(k in keys for k in ("CacheDirectory", "StateDirectory")),
               "no CacheDirectory= or StateDirectory= for the worker's cache")
    exec_start = get("ExecStart")
    expect(len(exec_start) == 1, "ExecStart= must appear once")
    words = shlex.split(exec_start[0].lstrip("-@:+!"))
    expect(os.path.basename(words[0]) == program and words[0].startswith("/"),
           f"ExecStart starts {words[0]}, not an absolute path to {program}")
    check_invocation(program, words[1:], flags, "ExecStart")
    if program == "tessera-worker":
        expect("%i" in (flag_value(words, "--name") or ""),
               "the worker's --name does not include the instance (%i)")
    # Every variable ExecStart uses is set by Environment= or the shipped example file.
    defined = set()
    for value in get("Environment"):
        defined |= {w.split("=", 1)[0] for w in shlex.split(value)}
    examples = {os.path.basename(f.lstrip("-")) for f in get("EnvironmentFile")}
    for example in examples:
        shipped = os.path.join(root, "deploy", "systemd", example.replace("-%i", ""))
        if os.path.exists(shipped):
            defined |= set(re.findall(r"^\s*(\w+)=", read(shipped), re.M))
    expect(any(os.path.exists(os.path.join(root, "deploy", "systemd", e)) for e in examples),
           f"no example of EnvironmentFile {' '.join(sorted(examples))} in deploy/systemd")
    provided = {"STATE_DIRECTORY", "CACHE_DIRECTORY", "RUNTIME_DIRECTORY", "LOGS_DIRECTORY",
                "CONFIGURATION_DIRECTORY"}
    if any(k.startswith("LoadCredential") for k in keys):
        provided.add("CREDENTIALS_DIRECTORY")
    used = set(re.findall(r"\$\{?(\w+)", exec_start[0]))
    undefined = used - defined - provided
    expect(not undefined, f"ExecStart uses {' '.join(sorted(undefined))}, defined nowhere")
    return f"{program}, {len(service)} settings"


def check_systemd_analyze(root):
    tool = shutil.which("systemd-analyze")
    if not tool:
        raise Skipped("systemd-analyze is not installed")
    folder = os.path.join(root, "deploy", "systemd")
    with tempfile.TemporaryDirectory() as tmp:
        units = []
        for name in sorted(os.listdir(folder)):
            if name.endswith(".service"):
                target = name.replace("@.service", "@1.service")
                shutil.copy(os.path.join(folder, name), os.path.join(tmp, target))
                units.append(os.path.join(tmp, target))
        out = subprocess.run([tool, "verify", "--man=no"] + units, capture_output=True,
                             text=True, timeout=60)
    # The binaries are not installed here: that complaint is expected.
    problems = [l for l in (out.stdout + out.stderr).splitlines()
                if l.strip() and "is not executable" not in l]
    expect(not problems, "; ".join(problems))
    return f"{len(units)} units"


def check_shellcheck(root):
    tool = shutil.which("shellcheck")
    if not tool:
        raise Skipped("shellcheck is not installed")
    scripts = [os.path.join(root, "deploy", p) for p in
               ("setup.sh", "docker-entrypoint.sh", "runtime-packages.sh", "make-secrets.sh",
                "build-image.sh", os.path.join("slurm", "tessera-workers.sbatch"))]
    scripts = [s for s in scripts if os.path.exists(s)]
    out = subprocess.run([tool, "-S", "warning"] + scripts, capture_output=True, text=True,
                         timeout=60)
    expect(out.returncode == 0, out.stdout.strip().replace("\n", " | ")[:2000])
    return f"{len(scripts)} scripts"


def check_kustomize(root):
    tool = shutil.which("kubectl")
    if not tool:
        raise Skipped("kubectl is not installed")
    out = subprocess.run([tool, "kustomize", os.path.join(root, "deploy", "kubernetes")],
                         capture_output=True, text=True, timeout=60)
    expect(out.returncode == 0, out.stderr.strip())
    docs = [d for d in yaml.safe_load_all(out.stdout) if d]
    return f"{len(docs)} objects rendered"


# ---------------------------------------------------------------------------------
# Security: TLS, tokens and where the secrets come from
# ---------------------------------------------------------------------------------

# Flags (and the variables that stand in for them) naming files with secrets or trust
# anchors; each must come from the platform's secret store.
SECRET_FILE_FLAGS = ("--tls-cert", "--tls-key", "--tls-client-ca", "--tokens", "--tls-ca",
                     "--token-file")
SECRET_FILE_VARIABLES = {"TESSERA_TLS_CA": "--tls-ca", "TESSERA_TLS_CERT": "--tls-cert",
                         "TESSERA_TLS_KEY": "--tls-key", "TESSERA_TOKEN_FILE": "--token-file",
                         "TESSERA_TOKENS_FILE": "--tokens",
                         "TESSERA_TLS_CLIENT_CA": "--tls-client-ca"}
# What a coordinator needs to listen off loopback, and what its callers need.
COORDINATOR_SECURITY = ("--tls-cert", "--tls-key", "--tokens")
CALLER_SECURITY = {"--tls-ca": "TESSERA_TLS_CA", "--token-file": "TESSERA_TOKEN_FILE"}
# Where the deployments keep generated secrets (git- and docker-ignored).
SECRETS_FOLDER = "deploy/secrets"


def is_loopback(listen):
    """Mirrors the coordinator's IsLoopbackAddress: unix sockets, localhost, ::1, 127/8."""
    if listen.startswith(("unix:", "unix-abstract:")):
        return True
    host = listen[7:] if listen.startswith("dns:///") else listen
    if host.startswith("["):
        host = host[1:host.find("]")] if "]" in host else host
    elif host.count(":") == 1:
        host = host.rsplit(":", 1)[0]
    host = host.lower()
    return host in ("localhost", "::1") or re.fullmatch(r"127(\.\d{1,3}){3}", host) is not None


class Invocation:
    """One place a deployment starts a program: its arguments, the environment it gets,
    and how a file path given to it is provided (None: fine, else why not)."""

    def __init__(self, where, program, words, env=None, source=None, listens=None):
        self.where, self.program, self.words = where, program, words
        self.env = env or {}
        self.source = source or (lambda path: None)
        self.listens = listens  # possible --listen values (None: the flag's own)

    def value(self, flag):
        v = flag_value(self.words, flag)
        if v is None and flag in SECRET_FILE_VARIABLES.values():
            names = [k for k, f in SECRET_FILE_VARIABLES.items() if f == flag]
            v = next((self.env[n] for n in names if self.env.get(n)), None)
        return v


def compose_invocations(root):
    doc, services = compose_services(root)
    declared = doc.get("secrets") or {}
    found = []
    for name, svc in services.items():
        entry = svc.get("entrypoint") or []
        entry = shlex.split(entry) if isinstance(entry, str) else [str(a) for a in entry]
        entry = [a for a in entry if os.path.basename(a) not in ("tini", "--")]
        program, words = program_of(entry + compose_argv(svc)) if entry else (None, [])
        if not program:
            program, words = program_of(compose_argv(svc))
        if program not in PROGRAMS:
            continue
        env = svc.get("environment") or {}
        if isinstance(env, list):
            env = dict(str(e).split("=", 1) if "=" in str(e) else (str(e), "") for e in env)
        env = {str(k): str(v) for k, v in env.items()}
        mounted = {}
        for s in svc.get("secrets") or []:
            if isinstance(s, str):
                mounted["/run/secrets/" + s] = s
            else:
                target = s.get("target", s.get("source"))
                target = target if target.startswith("/") else "/run/secrets/" + target
                mounted[target] = s.get("source")

        def source(path, mounted=mounted, name=name):
            secret = mounted.get(path)
            if secret is None:
                return (f"{path} is not one of service {name}'s Compose secrets "
                        f"({' '.join(sorted(mounted)) or 'none'})")
            spec = declared.get(secret)
            if not isinstance(spec, dict) or "file" not in spec:
                return f"secret {secret} is not declared with file: in the top-level secrets"
            where = os.path.normpath(os.path.join("deploy", spec["file"]))
            if not (where + "/").startswith(SECRETS_FOLDER + "/"):
                return f"secret {secret} is read from {where}, outside {SECRETS_FOLDER}/"
            return None

        found.append(Invocation(f"docker-compose.yml service {name}", program, words, env,
                                source))
    return found


def k8s_invocations(root):
    found = []
    for path, d in workloads(root):
        pod = d["spec"]["template"]["spec"]
        volumes = {v.get("name"): v for v in pod.get("volumes") or []}
        for c in pod.get("containers") or []:
            program, words = program_of((c.get("command") or []) + (c.get("args") or []))
            if program not in PROGRAMS:
                continue
            env = {e.get("name"): str(e.get("value", "")) for e in c.get("env") or []}
            mounts = c.get("volumeMounts") or []

            def source(p, mounts=mounts, volumes=volumes):
                m = mount_for(p, mounts)
                if m is None:
                    return f"{p} is on no volume"
                v = volumes.get(m["name"]) or {}
                secret = "secret" in v or any("secret" in s for s in
                                              (v.get("projected") or {}).get("sources") or [])
                if not secret:
                    return f"{p} is on volume {m['name']}, which is not a Secret"
                if not m.get("readOnly"):
                    return f"the Secret volume {m['name']} is not mounted readOnly"
                return None

            found.append(Invocation(f"{path} {d['kind']}/{d['metadata']['name']} container "
                                    f"{c.get('name')}", program, words, env, source))
    return found


def unit_environment(root, service):
    """Every value each variable may take: Environment= defaults and the shipped
    example environment files."""
    env = {}
    for kk, value in service:
        if kk == "Environment":
            for w in shlex.split(value):
                k, _, v = w.partition("=")
                env.setdefault(k, []).append(v)
        elif kk == "EnvironmentFile":
            shipped = os.path.join(root, "deploy", "systemd",
                                   os.path.basename(value.lstrip("-")).replace("-%i", ""))
            if os.path.exists(shipped):
                for k, v in re.findall(r"^\s*(\w+)=(.*)$", read(shipped), re.M):
                    env.setdefault(k, []).append(v.strip().strip('"'))
    return env


def systemd_invocations(root):
    found = []
    for name in ("tessera-coordinator.service", "tessera-worker@.service"):
        path = os.path.join(root, "deploy", "systemd", name)
        service = parse_unit(read(path)).get("Service") or []
        exec_start = [v for k, v in service if k == "ExecStart"]
        if not exec_start:
            continue
        words = shlex.split(exec_start[0].lstrip("-@:+!"))
        program = os.path.basename(words[0])
        env = unit_environment(root, service)
        inline = [k for k, _ in service if k.startswith("SetCredential")]
        expect(not inline, f"{name}: {' '.join(inline)}= puts a secret in the unit file")
        credentials = {v.split(":", 1)[0] for k, v in service
                       if k in ("LoadCredential", "LoadCredentialEncrypted")}

        def source(p, credentials=credentials):
            m = re.fullmatch(r"\$\{?CREDENTIALS_DIRECTORY\}?/([^/]+)|%d/([^/]+)", p)
            if not m:
                return f"{p} is not a systemd credential (${{CREDENTIALS_DIRECTORY}}/NAME)"
            cred = m.group(1) or m.group(2)
            if cred not in credentials:
                return f"{p}: no LoadCredential={cred}:..."
            return None

        listen = flag_value(words, "--listen") or ""
        listens = None
        var = re.fullmatch(r"\$\{?(\w+)\}?", listen)
        if var:
            listens = env.get(var.group(1)) or [listen]
        flat_env = {k: v[-1] for k, v in env.items()}
        found.append(Invocation(f"systemd/{name} ExecStart", program, words[1:], flat_env,
                                source, listens))
    return found


def dockerfile_invocations(root):
    _, stages = dockerfile(root)
    found = []
    for number, instr, args in stages[-1]["body"]:
        if instr == "CMD" and args.strip().startswith("["):
            program, words = program_of(json.loads(args))
            if program in PROGRAMS:
                found.append(Invocation(f"Dockerfile line {number} CMD", program, words))
    return found


def sbatch_invocations(root):
    text = read(os.path.join(root, "deploy", "slurm", "tessera-workers.sbatch"))
    return [Invocation(f"slurm/tessera-workers.sbatch line {n}", "tessera-worker", w)
            for n, w in invocations_in_shell(text, "tessera-worker", must_contain=r"\bsrun\b")]


def all_invocations(root):
    return (compose_invocations(root) + k8s_invocations(root) + systemd_invocations(root)
            + dockerfile_invocations(root) + sbatch_invocations(root))


def check_listen_security(root):
    """Every coordinator listening off loopback serves TLS and checks tokens; none is
    --insecure."""
    coordinators = [i for i in all_invocations(root) if i.program == "tessera-coordinator"]
    expect(coordinators, "no coordinator invocation found")
    off = 0
    for inv in coordinators:
        expect("--insecure" not in inv.words,
               f"{inv.where}: --insecure (plaintext or no tokens off loopback)")
        listens = sorted(set(inv.listens or [flag_value(inv.words, "--listen") or ""]))
        if all(is_loopback(l) for l in listens):
            continue
        off += 1
        missing = [f for f in COORDINATOR_SECURITY if not inv.value(f)]
        expect(not missing, f"{inv.where}: listens on {' or '.join(listens)} without "
                            f"{' '.join(missing)}")
    return f"{len(coordinators)} coordinators, {off} off loopback"


def check_caller_security(root):
    """Workers and CLI services connect over TLS with a token file."""
    callers = [i for i in all_invocations(root) if i.program != "tessera-coordinator"]
    expect(callers, "no worker or CLI invocation found")
    for inv in callers:
        missing = [f"{f} (or {var})" for f, var in CALLER_SECURITY.items()
                   if flag_value(inv.words, f) is None and not inv.env.get(var)]
        expect(not missing, f"{inv.where}: {inv.program} without {', '.join(missing)}")
    return f"{len(callers)} workers and clients"


def check_secret_sources(root):
    """Secret files come from Compose secrets, Kubernetes Secrets or systemd credentials."""
    checked = 0
    for inv in all_invocations(root):
        for flag in SECRET_FILE_FLAGS:
            path = inv.value(flag)
            if path is None:
                continue
            problem = inv.source(path)
            expect(problem is None, f"{inv.where}: {flag}: {problem}")
            checked += 1
    return f"{checked} secret files"


PEM_BLOCK = re.compile(r"-----BEGIN [A-Z0-9 ]+-----")
TOKEN_FLAG = re.compile(r"(?<![\w-])--token(?![\w-])")
# A token of `tessera token` (64 hex digits) or anything as long and random-looking;
# "sha256:" digests (image pins) are not secrets.
TOKEN_LIKE = re.compile(r"(?<![\w:])[0-9a-fA-F]{32,}(?![\w])")
TOKEN_VARIABLE = re.compile(r"\bTESSERA_TOKEN\b\s*[:=]\s*['\"]?([^\s'\"]+)")


def check_no_inline_secrets(root):
    """No key, certificate or token is written into a deployment file."""
    scanned = 0
    deploy = os.path.join(root, "deploy")
    for dirpath, dirnames, filenames in os.walk(deploy):
        if rel(root, dirpath) == SECRETS_FOLDER:
            dirnames[:] = []
            continue
        dirnames.sort()
        for name in sorted(filenames):
            path = os.path.join(dirpath, name)
            try:
                text = read(path)
            except UnicodeDecodeError:
                continue
            scanned += 1
            where = rel(root, path)
            for number, line in enumerate(text.splitlines(), 1):
                expect(not PEM_BLOCK.search(line), f"{where}:{number}: a PEM block "
                       "(keys and certificates are made by deploy/make-secrets.sh)")
                expect(not TOKEN_FLAG.search(line),
                       f"{where}:{number}: --token on a command line (every user of the "
                       "machine can read it in ps: use --token-file)")
                m = TOKEN_VARIABLE.search(line)
                expect(not m or m.group(1).startswith("$"),
                       f"{where}:{number}: TESSERA_TOKEN holds a token (use a token file)")
                expect(not TOKEN_LIKE.search(line),
                       f"{where}:{number}: a long hex string that looks like a token")
    for path, d in kubernetes_objects(root):
        expect(d.get("kind") != "Secret" or not (d.get("data") or d.get("stringData")),
               f"{path}: Secret/{d['metadata']['name']} holds data: create it from files "
               "instead (see kustomization.yaml)")
    return f"{scanned} files"


def check_secrets_ignored(root):
    """deploy/secrets/ is kept out of git and out of the image's build context."""
    gitignore = os.path.join(root, ".gitignore")
    expect(os.path.exists(gitignore), "no .gitignore")
    patterns = [l.strip().rstrip("/").lstrip("/") for l in read(gitignore).splitlines()]
    expect(SECRETS_FOLDER in patterns, f".gitignore does not ignore {SECRETS_FOLDER}/")
    dockerignore = os.path.join(root, "deploy", "Dockerfile.dockerignore")
    patterns = [l.strip().rstrip("/").lstrip("/") for l in read(dockerignore).splitlines()]
    expect(SECRETS_FOLDER in patterns or "deploy" in patterns,
           f"deploy/Dockerfile.dockerignore lets {SECRETS_FOLDER}/ into the build context")
    script = os.path.join(root, "deploy", "make-secrets.sh")
    expect(os.path.exists(script), "deploy/make-secrets.sh is missing")
    text = read(script)
    for command in ("cert ca", "cert server", "token --role worker", "token --role client"):
        expect(command in text, f"deploy/make-secrets.sh does not run `tessera {command}`")
    return None


# ---------------------------------------------------------------------------------

def run_all(root, build_dir, external, quiet=False, flags=None):
    report = Report(quiet)
    flags = flags or known_flags(root, build_dir)
    if not quiet:
        for program, (f, source) in sorted(flags.items()):
            print(f"flags of {program} from {source}: {' '.join(sorted(f))}")
    files = yaml_files(root)
    report.run("yaml files found under deploy/", lambda: expect(files, "none") or f"{len(files)}")
    for path in files:
        report.run(f"yaml parses: {rel(root, path)}", check_yaml_parses, path)
    report.run("kubernetes: apiVersion, kind, metadata.name", check_k8s_identity, root)
    report.run("kubernetes: kustomization lists every manifest", check_kustomization, root)
    report.run("kubernetes: workloads well-formed, flags exist", check_k8s_workload_shape,
               root, flags)
    report.run("kubernetes: coordinator PVC, probes, Service", check_k8s_coordinator, root)
    report.run("kubernetes: worker Deployment replicas, grace, target", check_k8s_worker, root)
    report.run("compose: coordinator, workers, volumes, healthcheck", check_compose, root, flags)
    report.run("dockerfile: packages match deploy/setup.sh", check_docker_packages, root)
    report.run("dockerfile: bookworm, Release build, sources, binaries, user",
               check_docker_build, root)
    report.run("dockerfile: entry point selects the program", check_entrypoint, root)
    report.run("slurm: sbatch starts workers with srun", check_sbatch, root, flags, external)
    report.run("systemd: tessera-coordinator.service", check_systemd_unit, root,
               "tessera-coordinator.service", flags)
    report.run("systemd: tessera-worker@.service", check_systemd_unit, root,
               "tessera-worker@.service", flags)
    report.run("security: coordinators off loopback have TLS and tokens",
               check_listen_security, root)
    report.run("security: workers and clients have a CA and a token file",
               check_caller_security, root)
    report.run("security: secret files come from the platform's secret store",
               check_secret_sources, root)
    report.run("security: no key or token inline", check_no_inline_secrets, root)
    report.run("security: deploy/secrets is ignored and made by make-secrets.sh",
               check_secrets_ignored, root)
    if external:
        report.run("systemd-analyze verify", check_systemd_analyze, root)
        report.run("shellcheck -S warning", check_shellcheck, root)
        report.run("kubectl kustomize", check_kustomize, root)
    return report


# Each mutation breaks a copy of the files in one way that a check must notice:
# (title, file, text, replacement, count[, a part of the name of the check that must fail]).
MUTATIONS = [
    ("broken YAML", "deploy/kubernetes/worker.yaml", "  replicas:", "  replicas: [", 1),
    ("worker replicas removed", "deploy/kubernetes/worker.yaml", "  replicas: ",
     "  # replicas: ", 1),
    ("object without a name", "deploy/kubernetes/coordinator.yaml", "  name: tessera-coordinator\n",
     "  nam: tessera-coordinator\n", 1),
    ("misspelt probe field", "deploy/kubernetes/coordinator.yaml", "readinessProbe:",
     "readinesProbe:", 1),
    ("state on a scratch volume", "deploy/kubernetes/coordinator.yaml",
     "- name: state\n              mountPath", "- name: tmp\n              mountPath", 1),
    ("Service removed", "deploy/kubernetes/coordinator.yaml", "kind: Service\n",
     "kind: ConfigMap\n", 1),
    ("unknown worker flag (k8s)", "deploy/kubernetes/worker.yaml", "- --threads", "- --thread", 1),
    ("setup.sh not run", "deploy/Dockerfile", "RUN bash /tmp/setup.sh", "RUN true /tmp/nothing", 1),
    ("extra package by hand", "deploy/Dockerfile", "RUN bash /tmp/setup.sh",
     "RUN apt-get install -y libfoo-dev && bash /tmp/setup.sh", 1),
    ("tests built in the image", "deploy/Dockerfile", "-DTESSERA_BUILD_TESTS=OFF",
     "-DTESSERA_BUILD_TESTS=ON", 1),
    ("source folder not copied", "deploy/Dockerfile", "COPY common common\n", "", 1),
    ("runs as root", "deploy/Dockerfile", "USER 10001:10001", "USER root", 1),
    ("entry point runs the wrong program", "deploy/docker-entrypoint.sh",
     'exec /usr/local/bin/tessera "$@"', 'exec /usr/local/bin/tessera-worker "$@"', 1),
    ("compose without replicas", "deploy/docker-compose.yml", "replicas:", "replicaz:", 1),
    ("compose worker at the wrong port", "deploy/docker-compose.yml", "- coordinator:50051",
     "- coordinator:50052", 1),
    ("sbatch unknown flag", "deploy/slurm/tessera-workers.sbatch", "--cache \"$TESSERA_CACHE",
     "--cache-dir \"$TESSERA_CACHE", 1),
    ("sbatch threads not from Slurm", "deploy/slurm/tessera-workers.sbatch",
     'threads="${SLURM_CPUS_PER_TASK:-1}"', 'threads="8"', 1),
    ("unit without TimeoutStopSec", "deploy/systemd/tessera-worker@.service", "TimeoutStopSec=",
     "#TimeoutStopSec=", 1),
    ("unit flag typo", "deploy/systemd/tessera-coordinator.service", "--listen ${",
     "--listn ${", 1),
    # Security: TLS, tokens, and secrets from the platform's store.
    ("compose coordinator without tokens", "deploy/docker-compose.yml",
     "      - --tokens\n      - /run/secrets/tokens\n", "", 1, "security: coordinators"),
    ("compose coordinator --insecure", "deploy/docker-compose.yml",
     "      - --tls-cert\n", "      - --insecure\n      - --tls-cert\n", 1, "security: coordinators"),
    ("compose worker secret not mounted", "deploy/docker-compose.yml",
     "      - worker.token\n    depends_on", "    depends_on", 1, "security: secret files"),
    ("compose secret from outside deploy/secrets", "deploy/docker-compose.yml",
     "file: ./secrets/tokens", "file: ../tokens", 1, "security: secret files"),
    ("compose CLI without a CA", "deploy/docker-compose.yml",
     "      TESSERA_TLS_CA: /run/secrets/ca.pem\n", "", 1, "security: workers and clients"),
    ("image default coordinator in plaintext", "deploy/Dockerfile",
     ', "--tokens", "/run/secrets/tokens"]', "]", 1, "security: coordinators"),
    ("k8s worker without a CA", "deploy/kubernetes/worker.yaml",
     "            - --tls-ca\n            - /etc/tessera/ca/ca.pem\n", "", 1, "security: workers and clients"),
    ("k8s tokens in a ConfigMap", "deploy/kubernetes/coordinator.yaml",
     "          secret:\n            secretName: tessera-tokens",
     "          configMap:\n            name: tessera-tokens", 1, "security: secret files"),
    ("k8s secret mounted writable", "deploy/kubernetes/worker.yaml",
     "              mountPath: /etc/tessera/token\n              readOnly: true",
     "              mountPath: /etc/tessera/token", 1, "security: secret files"),
    ("k8s gRPC probe on a TLS port", "deploy/kubernetes/coordinator.yaml",
     "            tcpSocket:\n              port: grpc", "            grpc:\n              port: 50051",
     1, "probes"),
    ("k8s Secret with data committed", "deploy/kubernetes/coordinator.yaml",
     "apiVersion: v1\nkind: Service\n",
     "apiVersion: v1\nkind: Secret\nmetadata:\n  name: tessera-tokens\nstringData:\n"
     "  tokens: worker w x\n---\napiVersion: v1\nkind: Service\n", 1, "security: no key or token inline"),
    ("systemd credential not loaded", "deploy/systemd/tessera-coordinator.service",
     "LoadCredential=tokens:", "#LoadCredential=tokens:", 1, "security: secret files"),
    ("systemd token from a plain path", "deploy/systemd/tessera-worker@.service",
     "--token-file ${CREDENTIALS_DIRECTORY}/token", "--token-file /etc/tessera/worker.token", 1, "security: secret files"),
    ("systemd coordinator off loopback in plaintext", "deploy/systemd/tessera-coordinator.service",
     " --tls-cert ${CREDENTIALS_DIRECTORY}/server.pem --tls-key ${CREDENTIALS_DIRECTORY}/server.key",
     "", 1, "security: coordinators"),
    ("sbatch worker without a token file", "deploy/slurm/tessera-workers.sbatch",
     ' --token-file "$TESSERA_TOKEN_FILE"', "", 1, "security: workers and clients"),
    ("token on a command line", "deploy/systemd/worker.env", "TESSERA_WORKER_ARGS=\n",
     "TESSERA_WORKER_ARGS=--token 0123456789abcdef\n", 1, "security: no key or token inline"),
    ("token in the environment", "deploy/docker-compose.yml",
     "      TESSERA_TOKEN_FILE: /run/secrets/client.token\n",
     "      TESSERA_TOKEN_FILE: /run/secrets/client.token\n      TESSERA_TOKEN: abcdefghijklmnopqrst\n", 1, "security: no key or token inline"),
    ("token pasted into a file", "deploy/systemd/coordinator.env", "TESSERA_COORDINATOR_ARGS=\n",
     "TESSERA_COORDINATOR_ARGS=\n# client alice " + "3f" * 32 + "\n", 1, "security: no key or token inline"),
    ("PEM key committed", "deploy/kubernetes/kustomization.yaml", "apiVersion:",
     "# -----BEGIN PRIVATE KEY-----\n# MC4CAQAwBQYDK2VwBCIEIA==\n# -----END PRIVATE KEY-----\n"
     "apiVersion:", 1, "security: no key or token inline"),
    ("secrets not docker-ignored", "deploy/Dockerfile.dockerignore", "deploy/secrets\n", "", 1, "security: deploy/secrets"),
    ("secrets not git-ignored", ".gitignore", "deploy/secrets/\n", "", 1, "security: deploy/secrets"),
]


def list_packages_dockerfile(root):
    """A Dockerfile that lists setup.sh's packages itself, minus one: the set compare
    must name the missing package."""
    path = os.path.join(root, "deploy", "Dockerfile")
    packages = sorted(setup_packages(root))
    text = read(path).replace("RUN bash /tmp/setup.sh",
                              "RUN apt-get update && apt-get install -y " + " ".join(packages[1:]))
    text = text.replace("COPY deploy/setup.sh /tmp/setup.sh\n", "")
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
    return packages[0]


def copy_for_checks(root, copy):
    """What the checks read: deploy/, the top-level files, and every top-level folder
    with just its CMakeLists.txt."""
    # Never the generated secrets (deploy/secrets/): the checks skip them anyway.
    shutil.copytree(os.path.join(root, "deploy"), os.path.join(copy, "deploy"),
                    ignore=lambda d, names: ["secrets"] if os.path.samefile(
                        d, os.path.join(root, "deploy")) else [])
    for name in os.listdir(root):
        source = os.path.join(root, name)
        if (name.startswith(".") and name != ".gitignore") or name in ("deploy", "build", "out"):
            continue
        if os.path.isfile(source):
            shutil.copy(source, os.path.join(copy, name))
        elif os.path.isdir(source):
            os.makedirs(os.path.join(copy, name))
            if os.path.exists(os.path.join(source, "CMakeLists.txt")):
                shutil.copy(os.path.join(source, "CMakeLists.txt"), os.path.join(copy, name))


def self_test(root, build_dir):
    flags = known_flags(root, build_dir)  # the same binaries for every copy
    baseline = run_all(root, build_dir, external=False, quiet=True, flags=flags)
    ok = baseline.failed == 0
    print(f"{'PASS' if ok else 'FAIL'} self-test baseline: the real files pass "
          f"({baseline.passed} checks)")
    passed, failed = int(ok), int(not ok)
    cases = [(m[0], m) for m in MUTATIONS] + [("Dockerfile listing one package too few", None)]
    for title, mutation in cases:
        with tempfile.TemporaryDirectory() as tmp:
            copy = os.path.join(tmp, "repo")
            copy_for_checks(root, copy)
            detail = ""
            wanted = None  # the check that must notice, where the mutation names one
            if mutation:
                _, path, old, new, count = mutation[:5]
                wanted = mutation[5] if len(mutation) > 5 else None
                target = os.path.join(copy, path)
                text = read(target)
                if old not in text:
                    print(f"FAIL self-test {title}: {path} no longer contains {old!r}")
                    failed += 1
                    continue
                with open(target, "w", encoding="utf-8") as f:
                    f.write(text.replace(old, new, count))
            else:
                detail = list_packages_dockerfile(copy)
            report = run_all(copy, build_dir, external=False, quiet=True, flags=flags)
            caught = report.failed > 0
            if wanted:
                caught = caught and any(wanted in f for f in report.failures)
            if detail:  # the message must name the package that is missing
                caught = caught and any(detail in m for m in report.messages)
            print(f"{'PASS' if caught else 'FAIL'} self-test {title}: "
                  + (f"caught by {report.failures[0]}: {report.messages[0][:160]}"
                     if caught else "not noticed" + (f" by {wanted!r}" if wanted else "")))
            passed += caught
            failed += not caught
    return passed, failed


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", nargs="?", default=os.path.dirname(here),
                        help="repository root (default: this script's parent folder)")
    parser.add_argument("--build-dir", help="where CMake built the binaries (default ROOT/build)")
    parser.add_argument("--no-external", action="store_true",
                        help="skip bash -n, shellcheck, systemd-analyze and kubectl")
    parser.add_argument("--self-test", action="store_true",
                        help="check that the checks catch known breakages")
    args = parser.parse_args()
    root = os.path.abspath(args.root)
    build_dir = os.path.abspath(args.build_dir or os.path.join(root, "build"))
    if args.self_test:
        passed, failed = self_test(root, build_dir)
        print(f"{passed} passed, {failed} failed")
        return 1 if failed else 0
    report = run_all(root, build_dir, external=not args.no_external)
    print(f"{report.passed} passed, {report.failed} failed, {report.skipped} skipped")
    return 1 if report.failed else 0


if __name__ == "__main__":
    sys.exit(main())
