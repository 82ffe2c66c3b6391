"""Evaluate a model's GLSL for CPU work: transform feedback over batches of direction pairs.

A BRDF Explorer file is GLSL alone; fits, plots and the energy check need its values on
the CPU side. One thread owns a headless context (GL contexts belong to the thread that
made them, and the fitter evaluates from a pool): a request runs there, each batch of
pairs goes through a vertex shader that calls the model's `brdf_<id>` and writes its value
by transform feedback. Parameters that are the same for every pair are uniforms; per-pair
parameters ride along as vertex attributes.

`check` compiles a model and evaluates it on probe pairs in a child process with a CPU-time
limit, so that a file whose GLSL never finishes is refused instead of hanging the lab (the
file's loops are bounded by the GLSL itself: glsl_text.guarded_loops).
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import moderngl
import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.io.user_cache import code_digest, entry_key, read_entry, write_entry
from brdflab.models.files import backend
from brdflab.models.files.glsl_text import OVER
from brdflab.models.files.limits import MAX_LOOP_STEPS
from brdflab.render import gil_free
from brdflab.render.glsl import GLSL_VERSION, MAX_PARAMS, shader_source

BATCH = 1 << 16  # pairs per draw
CHECK_CPU_SECONDS = 30  # the probe child's CPU time (RLIMIT_CPU): the same budget on an idle or a loaded machine
HANG_SECONDS = 120.0  # wall clock, for a child that waits without computing
_LOG_LINE = re.compile(r"(\d+):(\d+)\((\d+)\):\s*(?:error|warning)?:?\s*(.*)")


def _vertex_shader(model, per_pair: bool) -> tuple[str, int]:
    """The program's source and the line (1-based) where the model's own GLSL starts."""
    head = GLSL_VERSION + "in vec3 in_wi;\nin vec3 in_wo;\n"
    if per_pair:
        head += "".join(f"in vec4 in_p{k};\n" for k in range(MAX_PARAMS // 4))
    else:
        head += f"uniform float u_p[{MAX_PARAMS}];\n"
    head += f"out vec3 out_f;\nout float out_over;\n#define NP {MAX_PARAMS}\n" + shader_source("common.glsl") + "\n"
    start = head.count("\n") + 1
    source = model.glsl_source()
    gid = model.glsl_id
    value = f"brdf_{gid}_rgb(in_wi, in_wo, p)" if model.colour else f"vec3(brdf_{gid}(in_wi, in_wo, p))"
    fill = ([f"p[{k}] = in_p{k // 4}[{k % 4}];" for k in range(MAX_PARAMS)] if per_pair
            else [f"p[{k}] = u_p[{k}];" for k in range(MAX_PARAMS)])
    main = ("void main() {\n    float p[NP];\n    " + " ".join(fill)
            + f"\n    out_f = {value};\n    out_over = {gid}_{OVER} ? 1.0 : 0.0;\n}}\n")
    return head + source + main, start


def compile_message(model, log: str, start: int) -> str:
    """The compiler's first error, at the model file's own line where it lies there."""
    for line in str(log).splitlines():
        m = _LOG_LINE.search(line)
        if m and "error" in line.lower():
            where = int(m.group(2)) - start  # 0-based line within the model's GLSL
            offset = getattr(getattr(model, "glsl", None), "line_offset", None)
            text = m.group(4).strip()
            if offset is not None and where >= 1:
                return f"line {offset + where}: GLSL error: {text}"
            return f"GLSL error in the code the lab wraps around the file: {text}"
    first = next((l for l in str(log).splitlines() if l.strip()), "the GLSL does not compile")
    return f"GLSL error: {first.strip()}"


class _GlThread:
    """A thread that owns a headless context and runs every request on it."""

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdflab-glsl")
        self._ctx = None
        self._programs: dict = {}

    def run(self, fn, *args):
        return self._pool.submit(fn, *args).result()

    def context(self):
        if self._ctx is None:
            from brdflab.render.context import create_context

            self._ctx = create_context()
        return self._ctx

    def program(self, model, per_pair: bool):
        key = (model.glsl_id, model.origin.sha256 if model.origin else "", per_pair)
        if key not in self._programs:
            ctx = self.context()
            source, start = _vertex_shader(model, per_pair)
            try:
                prog = ctx.program(vertex_shader=source, varyings=["out_f", "out_over"])
            except Exception as e:  # moderngl raises plain Exceptions carrying the compiler log
                raise BRDFLabError(compile_message(model, e, start), getattr(model.origin, "path", None)) from None
            self._programs[key] = prog
        return self._programs[key]

    def evaluate(self, model, wi: np.ndarray, wo: np.ndarray, params: list) -> np.ndarray:
        shape = np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1], *[np.shape(v) for v in params])
        n = int(np.prod(shape))
        wi_f = np.ascontiguousarray(np.broadcast_to(wi, shape + (3,)).reshape(n, 3), np.float32)
        wo_f = np.ascontiguousarray(np.broadcast_to(wo, shape + (3,)).reshape(n, 3), np.float32)
        per_pair = any(np.size(v) > 1 for v in params)
        ctx = self.context()
        prog = self.program(model, per_pair)
        if not per_pair:
            values = np.zeros(MAX_PARAMS, np.float32)
            values[: len(params)] = [float(np.asarray(v).ravel()[0]) for v in params]
            if "u_p" in prog:
                prog["u_p"].write(values[: prog["u_p"].array_length].tobytes())
        else:
            pvals = np.zeros((n, MAX_PARAMS), np.float32)
            for k, v in enumerate(params):
                pvals[:, k] = np.broadcast_to(np.asarray(v, float), shape).reshape(n)
        out = np.empty((n, 4), np.float32)  # the value, and whether its loops ran past MAX_LOOP_STEPS
        for s in range(0, n, BATCH):
            e = min(n, s + BATCH)
            arrays = [(wi_f[s:e], ["in_wi"], "3f"), (wo_f[s:e], ["in_wo"], "3f")]
            if per_pair:
                arrays.append((pvals[s:e], [f"in_p{k}" for k in range(MAX_PARAMS // 4)], "4f"))
            buffers, content = [], []
            for data, names, fmt in arrays:
                present = [nm for nm in names if nm in prog]
                if not present:
                    continue  # the compiler dropped what the model does not read
                buffers.append(ctx.buffer(np.ascontiguousarray(data).tobytes()))
                pad = f"{int(fmt[0]) * 4}x"
                content.append((buffers[-1], " ".join(fmt if nm in present else pad for nm in names), *present))
            result = ctx.buffer(reserve=(e - s) * 16)
            vao = ctx.vertex_array(prog, content)
            gil_free.transform_points(ctx, vao, result, e - s)
            out[s:e] = np.frombuffer(result.read(), np.float32).reshape(-1, 4)
            for b in buffers + [result]:
                b.release()
            vao.release()
        over = out[:, 3] > 0.0
        if over.any():
            k = int(np.argmax(over))
            raise BRDFLabError(f"its GLSL's loops run past {MAX_LOOP_STEPS:,} steps in one evaluation (e.g. at wi = "
                               f"{_shown(wi_f[k])}, wo = {_shown(wo_f[k])}): the lab "
                               "stops them there, so its value would be wrong", getattr(model.origin, "path", None))
        return out[:, :3].astype(float).reshape(shape + (3,))


def _shown(w: np.ndarray) -> list[float]:
    return np.round(w.astype(float), 3).tolist()


class GlslEvaluator:
    """The render layer's answer to `brdflab.models.files.backend`."""

    def __init__(self) -> None:
        self._thread = _GlThread()
        self._checked: dict[str, tuple[str | None, str | None]] = {}  # sha256 → (problem, undefined)

    def evaluate(self, model, wi, wo, params) -> np.ndarray:
        return self._thread.run(self._thread.evaluate, model, np.asarray(wi, float), np.asarray(wo, float), params)

    def check(self, model) -> None:
        """Compile and probe-evaluate the model in a child process with a time limit, once per
        content: the child's verdict is kept in the user's cache (see `check_key`); where it is
        undefined goes to `model.undefined`."""
        key = check_key(model)
        if key not in self._checked:
            self._checked[key] = _cached_verdict(key) or _probe_and_keep(model, key)
        found, undefined = self._checked[key]
        if found:
            raise BRDFLabError(found, model.origin.path)
        model.note_undefined(undefined)


CHECKS = "model_checks"  # the user cache's folder of verdicts
CHECK_CODE = ("models/files", "render/context.py", "render/glsl.py", "render/model_eval.py", "render/model_probe.py")


def check_key(model) -> str:
    """What decides a check's verdict: the file's content, the name the model takes (the GLSL
    calls brdf_<name>), and the code that reads, translates and probes it. A 100-file model
    folder cost each command 0.2–1.2 s per file, probing every file again (issue 35)."""
    return entry_key({"file": model.origin.sha256, "name": model.name, "code": code_digest(*CHECK_CODE),
                      "gl": moderngl.__version__})


def _cached_verdict(key: str) -> tuple[str | None, str | None] | None:
    entry = read_entry(CHECKS, key)
    if entry is None or set(entry) != {"problem", "undefined"}:
        return None
    if not all(v is None or isinstance(v, str) for v in entry.values()):
        return None
    return entry["problem"], entry["undefined"]


def _probe_and_keep(model, key: str) -> tuple[str | None, str | None]:
    """The child's verdict, kept when it is the child's own answer (not a time limit reached,
    which a loaded machine may cause, nor a child that could not answer)."""
    problem, undefined, answered = probe_in_child(model)
    if answered:
        write_entry(CHECKS, key, {"problem": problem, "undefined": undefined})
    return problem, undefined


def probe_command(model) -> list[str]:
    return [sys.executable, "-m", "brdflab.render.model_probe", str(model.origin.path), model.origin.sha256, model.name]


def _limit_cpu(pid: int) -> None:
    """At most CHECK_CPU_SECONDS of CPU time for a child (then SIGXCPU ends it), set from here
    (prlimit: a preexec_fn is unsafe in a process with threads, as the lab's is), or less where
    the lab itself runs under a lower hard limit (which a child cannot raise)."""
    import resource

    _, hard = resource.getrlimit(resource.RLIMIT_CPU)
    soft = CHECK_CPU_SECONDS if hard == resource.RLIM_INFINITY else min(CHECK_CPU_SECONDS, hard)
    try:
        resource.prlimit(pid, resource.RLIMIT_CPU, (soft, hard))
    except ProcessLookupError:
        pass  # it has ended already


def probe_in_child(model) -> tuple[str | None, str | None, bool]:
    """The one-line problem of the model's GLSL (None if it compiles and evaluates probe pairs
    within CHECK_CPU_SECONDS of CPU time in a child process), where it is undefined, and
    whether the child answered (False: a limit ended it, or it died)."""
    from brdflab.models.files.library import PROBE_PAIRS

    ran_out = (f"its GLSL did not finish evaluating {PROBE_PAIRS:,} direction pairs in {CHECK_CPU_SECONDS:g} s "
               "of CPU time (a lobe takes milliseconds): refused")
    with subprocess.Popen(probe_command(model), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as child:
        _limit_cpu(child.pid)
        try:
            stdout, stderr = child.communicate(timeout=HANG_SECONDS)
        except subprocess.TimeoutExpired:
            child.kill()
            child.communicate()
            return ran_out, None, False
    if child.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        return ran_out, None, False
    lines = [l for l in stdout.splitlines() if l.startswith("{")]
    if not lines:
        tail = (stderr.strip().splitlines() or ["no answer"])[-1]
        return f"its GLSL could not be checked: {tail}", None, False
    answer = json.loads(lines[-1])
    return answer.get("problem"), answer.get("undefined"), True


backend.install(GlslEvaluator())
