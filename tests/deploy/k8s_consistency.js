// Cross-document checks of the rendered deploy/k8s that no schema can make: the Service selects
// the master's pods and the workers connect to it by name and port, each worker renders on as
// many threads as the CPU it requests, every Secret and PVC a pod mounts is in the render, the
// pods run as the image's non-root user and can read the token Secret, the master's script refuses
// the placeholder token, and the workers spread over nodes.
// With a second render, made with another token, it checks that a new token rolls out new pods:
// both Deployments' pod templates change (they name the Secret, whose name carries its hash).
// usage: node k8s_consistency.js FILE [FILE_OTHER_TOKEN]   (FILE "-" reads standard input; each
//        one kubectl kustomize render)
'use strict';
const fs = require('fs');
const yaml = require('js-yaml');

const file = process.argv[2] || '-';
const load = (f) => yaml.loadAll(fs.readFileSync(f === '-' ? 0 : f, 'utf8')).filter(Boolean);
const docs = load(file);
const otherToken = process.argv[3] ? load(process.argv[3]) : null;
const problems = [];
let checks = 0;
function check(ok, what) {
  checks++;
  if (!ok) problems.push(what);
}
const find = (kind, name) => docs.find((d) => d.kind === kind && d.metadata && d.metadata.name === name);
const matches = (selector, labels) =>
  Object.entries(selector || {}).every(([k, v]) => labels && labels[k] === v);

const master = find('Deployment', 'rtc-master');
const worker = find('Deployment', 'rtc-worker');
const service = find('Service', 'rtc-master');
check(master && worker && service, 'the render has Deployments rtc-master and rtc-worker and Service rtc-master');
if (problems.length === 0) {
  const masterPod = master.spec.template;
  const workerPod = worker.spec.template;
  check(matches(service.spec.selector, masterPod.metadata.labels), 'Service rtc-master selects the master pods');
  check(!matches(service.spec.selector, workerPod.metadata.labels), 'Service rtc-master does not select worker pods');
  for (const d of [master, worker]) {
    check(matches(d.spec.selector.matchLabels, d.spec.template.metadata.labels),
          `${d.metadata.name}: selector matches its pod template`);
  }
  check(master.spec.replicas === 1, 'exactly one master');

  const masterContainer = masterPod.spec.containers[0];
  const workerContainer = workerPod.spec.containers[0];
  // A flag's value, also inside a `sh -c` script (split at white space and line continuations).
  const argAfter = (c, flag) => {
    const argv = [...(c.command || []), ...(c.args || [])].flatMap((a) => a.split(/[\s\\]+/).filter(Boolean));
    const i = argv.indexOf(flag);
    return i >= 0 ? argv[i + 1] : undefined;
  };
  const listen = argAfter(masterContainer, '--listen') || '';
  const masterPort = Number(listen.split(':').pop());
  check(masterContainer.ports.some((p) => p.containerPort === masterPort), `master's container port is its --listen ${listen}`);
  const connect = argAfter(workerContainer, '--connect') || '';
  const [host, port] = connect.split(':');
  check(host === service.metadata.name, `workers --connect ${connect} names the Service ${service.metadata.name}`);
  const servicePort = service.spec.ports.find((p) => p.port === Number(port));
  check(servicePort !== undefined, `workers --connect ${connect}: the Service has port ${port}`);
  if (servicePort) {
    const target = servicePort.targetPort;
    const targetPort = typeof target === 'string' ? (masterContainer.ports.find((p) => p.name === target) || {}).containerPort : target;
    check(targetPort === masterPort, `Service port ${port} reaches the master's --listen port ${masterPort}`);
  }
  check(argAfter(masterContainer, '--token-file') !== undefined && argAfter(workerContainer, '--token-file') !== undefined,
        'master and workers use --token-file');

  // Threads follow the CPU request: --threads $(RTC_THREADS), RTC_THREADS = requests.cpu.
  const threads = argAfter(workerContainer, '--threads');
  const env = (workerContainer.env || []).find((e) => `$(${e.name})` === threads);
  const ref = env && env.valueFrom && env.valueFrom.resourceFieldRef;
  check(ref && ref.resource === 'requests.cpu' && (ref.containerName || workerContainer.name) === workerContainer.name,
        `worker --threads ${threads} comes from its own requests.cpu`);
  const res = workerContainer.resources || {};
  check(res.requests && res.limits && String(res.requests.cpu) === String(res.limits.cpu),
        'worker CPU request equals its limit (threads = CPUs it may use)');

  // Spread over nodes.
  const anti = workerPod.spec.affinity && workerPod.spec.affinity.podAntiAffinity;
  const terms = anti ? [...(anti.preferredDuringSchedulingIgnoredDuringExecution || []).map((t) => t.podAffinityTerm),
                        ...(anti.requiredDuringSchedulingIgnoredDuringExecution || [])] : [];
  check(terms.some((t) => t.topologyKey === 'kubernetes.io/hostname' && matches(t.labelSelector.matchLabels, workerPod.metadata.labels)),
        'worker podAntiAffinity on kubernetes.io/hostname selects the worker pods');

  for (const d of [master, worker]) {
    const pod = d.spec.template.spec;
    check(pod.securityContext && pod.securityContext.runAsNonRoot === true && pod.securityContext.runAsUser === 10001,
          `${d.metadata.name}: runs as the image's user 10001, non-root`);
    for (const v of pod.volumes || []) {
      if (v.secret) {
        check(find('Secret', v.secret.secretName), `${d.metadata.name}: Secret ${v.secret.secretName} is in the render`);
        // The Secret's files belong to root (group: the pod's fsGroup, when it has one), with
        // defaultMode's bits (0644 unless given): the non-root user reads them through "other",
        // or through the group when fsGroup makes it one of the user's groups.
        const mode = v.secret.defaultMode === undefined ? 0o644 : Number(v.secret.defaultMode);
        const sc = pod.securityContext || {};
        const readable = (mode & 0o004) !== 0 || ((mode & 0o040) !== 0 && sc.fsGroup !== undefined);
        check(readable, `${d.metadata.name}: user ${sc.runAsUser} can read Secret ` +
              `${v.secret.secretName}'s files (mode 0${mode.toString(8)}, fsGroup ${sc.fsGroup})`);
      }
      if (v.persistentVolumeClaim) {
        check(find('PersistentVolumeClaim', v.persistentVolumeClaim.claimName),
              `${d.metadata.name}: PVC ${v.persistentVolumeClaim.claimName} is in the render`);
      }
    }
  }
  // The master's start script refuses the repository's placeholder token (anyone can read it),
  // and only it: run with the token path pointed at a file and no rtc-master on PATH.
  const script = masterContainer.command[masterContainer.command.length - 1];
  const { spawnSync } = require('child_process');
  const os = require('os');
  const path = require('path');
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'rtc-k8s-token-'));
  const tokenPath = path.join(dir, 'token');
  const runWith = (token) => {
    fs.writeFileSync(tokenPath, token);
    return spawnSync('/bin/sh', ['-c', script.split('/var/run/rtc/token').join(tokenPath)],
                     { env: { PATH: dir }, encoding: 'utf8', timeout: 10000 });
  };
  const placeholder = fs.readFileSync(path.join(__dirname, '..', '..', 'deploy', 'k8s', 'token'), 'utf8').trim();
  const refused = runWith(placeholder + '\n');
  check(refused.status === 1 && /placeholder/.test(refused.stderr),
        `the master's script refuses the placeholder token (exit ${refused.status}: ${refused.stderr.trim()})`);
  const random = runWith('0123456789abcdef0123456789abcdef\n');
  check(!/placeholder/.test(random.stderr) && random.status !== 1,
        `the master's script takes any other token (exit ${random.status}: ${random.stderr.trim()})`);
  fs.rmSync(dir, { recursive: true, force: true });

  // A new token rolls out new pods: the pods read the token once, at start.
  if (otherToken) {
    const secretsOf = (d) => (d.spec.template.spec.volumes || []).filter((v) => v.secret).map((v) => v.secret.secretName);
    for (const d of [master, worker]) {
      const o = otherToken.find((x) => x.kind === 'Deployment' && x.metadata.name === d.metadata.name);
      check(o && JSON.stringify(o.spec.template) !== JSON.stringify(d.spec.template),
            `${d.metadata.name}: another token changes the pod template (it names Secrets ` +
            `${secretsOf(d).join(', ')}, then ${o ? secretsOf(o).join(', ') : 'no Deployment'}), so the pods roll`);
      for (const name of o ? secretsOf(o) : []) {
        check(otherToken.some((x) => x.kind === 'Secret' && x.metadata.name === name),
              `${d.metadata.name}: with another token, Secret ${name} is in the render`);
      }
    }
  }

  const hpa = docs.find((d) => d.kind === 'HorizontalPodAutoscaler');
  if (hpa) {
    check(hpa.spec.scaleTargetRef.kind === 'Deployment' && hpa.spec.scaleTargetRef.name === 'rtc-worker',
          'the HorizontalPodAutoscaler scales Deployment rtc-worker');
  }
}
for (const p of problems) console.error(`FAIL ${p}`);
console.log(`${checks - problems.length} passed, ${problems.length} failed`);
process.exit(problems.length ? 1 : 0);
