"""`coadapt handoff`: a run's design as a folder with its model files, its controller as
ONNX (checked against torch), policy.json, the design sheet and a check script that walks
the robot in MuJoCo without coadapt. Real physics: a tiny Kuafu run fine-tuned from the
shipped flat policy, and the example plugin's quadruped."""

from __future__ import annotations

import ast
import json
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.cli import main
from coadapt_core.errors import UserError
from coadapt_core.handoff import model_files
from coadapt_core.handoff.policy import ONNX_TOLERANCE, missing_deploy_modules
from tests.conftest import run_cli

needs_deploy = pytest.mark.skipif(
    bool(missing_deploy_modules()), reason="needs the deploy extra (coadapt[deploy])"
)

#: runs a script with every coadapt import refused, so it can only use numpy, mujoco, onnxruntime
NO_COADAPT = (
    "import runpy, sys; sys.modules['coadapt_core'] = None; sys.modules['coadapt_plugins'] = None; "
    "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
)


def run_without_coadapt(folder: Path, script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", NO_COADAPT, script, *args],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )


# -- without a run ------------------------------------------------------------------------------
def test_without_the_deploy_extra_one_line_naming_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # as if it were not installed
    assert "onnxruntime" in missing_deploy_modules()
    assert main(["handoff", "some-run"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "onnxruntime" in err[0] and "coadapt[deploy]" in err[0]


@needs_deploy
def test_unknown_run_is_one_line_and_exit_2(tmp_path, capsys):
    assert main(["handoff", "no-such-run", "--runs-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no-such-run" in err[0] and "config.yaml" in err[0]


def _stl(path: Path) -> None:
    """A binary STL tetrahedron."""
    v = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]], dtype=np.float32)
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = bytearray(b"\0" * 80 + struct.pack("<I", len(faces)))
    for a, b, c in faces:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        data += struct.pack("<12fH", *n, *v[a], *v[b], *v[c], 0)
    path.write_bytes(bytes(data))


class _Model:
    def __init__(self, mjcf: str, urdf: str):
        self.formats = {"mjcf": mjcf, "urdf": urdf}

    def text(self, fmt: str) -> str:
        return self.formats[fmt]


class _MeshRobot:
    name = "meshy"


def test_model_files_carry_every_referenced_mesh(tmp_path, monkeypatch):
    """A mesh named relative to the plugin's folder (through the MJCF's meshdir) and one by
    absolute path are copied into assets/; the written MJCF compiles from the folder alone."""
    import mujoco

    home, elsewhere, out = tmp_path / "plugin", tmp_path / "elsewhere", tmp_path / "out"
    for folder in (home / "meshes", elsewhere, out):
        folder.mkdir(parents=True)
    _stl(home / "meshes" / "foot.stl")
    _stl(elsewhere / "foot.stl")  # the same file name from another folder: kept apart
    monkeypatch.setattr(model_files, "robot_folder", lambda robot: home)
    mjcf = f"""<mujoco><compiler meshdir="meshes"/>
  <asset><mesh name="a" file="foot.stl"/><mesh name="b" file="{elsewhere / "foot.stl"}"/></asset>
  <worldbody><body name="base"><freejoint/><geom type="mesh" mesh="a"/>
    <geom type="mesh" mesh="b" pos="0.1 0 0"/></body></worldbody>
</mujoco>"""
    urdf = (
        '<robot name="r"><link name="base"><visual><geometry><mesh '
        'filename="package://meshes/foot.stl"/>'
        "</geometry></visual></link></robot>"
    )
    written = model_files.write_model_files(_MeshRobot(), _Model(mjcf, urdf), out)
    assert sorted(p.name for p in written.assets) == ["foot.stl", "foot_1.stl"]
    model = mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
    assert model.nmesh == 2
    assert 'filename="assets/foot.stl"' in (out / "robot.urdf").read_text()
    # a reference that resolves nowhere is one line naming it
    with pytest.raises(UserError, match=r"missing\.stl"):
        model_files.write_model_files(
            _MeshRobot(),
            _Model(mjcf.replace('file="foot.stl"', 'file="missing.stl"'), urdf),
            tmp_path / "out2",
        )


def test_model_files_write_the_meshes_a_model_carries(tmp_path, monkeypatch):
    """A URDF mesh the model carries in memory (format "urdf:FILE", a mesh stretched for the
    design) is written into assets/ from there, named apart from a copied file of the same
    name; nothing is looked up on disk for it."""
    home, out = tmp_path / "plugin", tmp_path / "out"
    (home / "meshes").mkdir(parents=True)
    out.mkdir()
    _stl(home / "meshes" / "shin.obj")
    stretched = "v 0 0 0\nv 0.1 0 0\nv 0 0.2 0\nf 1 2 3\n"
    urdf = (
        '<robot name="r"><link name="base"><visual><geometry><mesh filename="shin.obj"/>'
        '</geometry></visual><collision><geometry><mesh filename="package://meshes/shin.obj"/>'
        "</geometry></collision></link></robot>"
    )
    model = _Model("<mujoco/>", urdf)
    model.formats["urdf:shin.obj"] = stretched

    monkeypatch.setattr(model_files, "robot_folder", lambda robot: home)
    written = model_files.write_model_files(_MeshRobot(), model, out)
    text = (out / "robot.urdf").read_text()
    assert 'filename="assets/shin.obj"' in text and 'filename="assets/shin_1.obj"' in text
    assert (out / "assets" / "shin.obj").read_text() == stretched
    assert (out / "assets" / "shin_1.obj").read_bytes() == (
        home / "meshes" / "shin.obj"
    ).read_bytes()
    assert sorted(p.name for p in written.assets) == ["shin.obj", "shin_1.obj"]


def _random_policy_state(seed: int) -> dict:
    """A saved state of a small random learner whose observation normaliser has seen data."""
    import torch

    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.ppo import PPO, Dims

    torch.manual_seed(seed)
    config = TrainConfig(hidden=(16, 8))
    dims = Dims(num_obs=6, num_critic_obs=7, num_design=2, num_actions=3, num_metrics=1)
    ppo = PPO(dims, config, torch.device("cpu"))
    ppo.obs_norm.update(2.0 * torch.randn(300, 6) - 1.0)
    return {
        "dims": vars(dims),
        "train_config": config.to_dict(),
        "objectives": ["torque"],
        "ppo": ppo.state_dict(),
    }


def test_the_specialised_policy_is_the_learners_own_mean_to_the_bit():
    """The handoff's torch module wraps the learner's mean (`PPO.mean_actor` of the policy
    `load_policy` rebuilds): the actions of `act_inference`, clipped, equal to the bit, and
    their joint targets; the mean is a copy, so loading another policy into the learner
    afterwards leaves it as it was; a design of the wrong length is one `UserError`."""
    import torch

    from coadapt_core.handoff.policy import SpecialisedPolicy, torch_actions
    from coadapt_core.learning.checkpoints import load_policy

    state = _random_policy_state(0)
    obs = (4.0 * np.random.default_rng(1).standard_normal((50, 6))).astype(np.float32)
    xi = np.array([0.3, -0.7])
    default = np.array([0.1, 0.0, -0.1])
    policy = SpecialisedPolicy(state, xi, default, action_scale=0.5, action_clip=0.4)
    assert not policy.training and not policy.actor.training
    with torch.no_grad():
        actions, targets = policy(torch.as_tensor(obs))
    reference = np.clip(torch_actions(state, obs, xi), -0.4, 0.4)
    assert 0.0 < np.mean(np.abs(reference) == np.float32(0.4)) < 1.0  # the clip bites on some
    np.testing.assert_array_equal(actions.numpy(), reference)
    np.testing.assert_array_equal(
        targets.numpy(), default.astype(np.float32) + np.float32(0.5) * reference
    )

    learner = load_policy(state)
    mean = learner.mean_actor()
    x = torch.as_tensor(obs)
    design = torch.as_tensor(xi, dtype=torch.float32).expand(len(obs), -1)
    with torch.no_grad():
        first = mean(x, design)
    np.testing.assert_array_equal(first.numpy(), torch_actions(state, obs, xi))
    learner.load_actor(_random_policy_state(1)["ppo"])
    with torch.no_grad():
        assert torch.equal(mean(x, design), first)
        assert (learner.act_inference(x, design) - first).abs().max() > 1e-2
    with pytest.raises(UserError, match="takes 2 design values, the design has 3"):
        SpecialisedPolicy(state, np.zeros(3), default, action_scale=0.5, action_clip=0.4)


@needs_deploy
@pytest.mark.slow
def test_onnx_graph_bakes_the_design_and_matches_the_learner(tmp_path):
    """A random policy with non-trivial normaliser statistics: the graph's actions equal the
    learner's `act_inference` (then clipped), for any batch size; another design input gives
    other actions (the design is a constant of the graph)."""
    import torch

    from coadapt_core.handoff.policy import (
        SpecialisedPolicy,
        export_onnx,
        onnx_actions,
        verify_onnx,
    )
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.ppo import PPO, Dims

    torch.manual_seed(0)
    config = TrainConfig(hidden=(64, 32))
    dims = Dims(num_obs=30, num_critic_obs=36, num_design=2, num_actions=4, num_metrics=1)
    ppo = PPO(dims, config, torch.device("cpu"))
    ppo.obs_norm.update(3.0 * torch.randn(500, 30) + 1.0)
    state = {
        "dims": vars(dims),
        "train_config": config.to_dict(),
        "objectives": ["torque"],
        "ppo": ppo.state_dict(),
    }
    default = np.array([0.1, -0.2, 0.3, -0.4])
    obs = (3.0 * np.random.default_rng(0).standard_normal((200, 30)) + 1.0).astype(np.float32)
    paths = {}
    for label, xi in (("a", np.array([0.5, -0.5])), ("b", np.array([-0.5, 0.9]))):
        policy = SpecialisedPolicy(state, xi, default, action_scale=0.25, action_clip=10.0)
        paths[label] = export_onnx(policy, tmp_path / f"{label}.onnx", {"robot": "test"})
        check = verify_onnx(paths[label], state, obs, xi, default, 0.25, 10.0)
        assert (
            check["max_abs_action_difference"] <= 1e-5
            and check["max_abs_target_difference"] <= 1e-5
        )
    one, _ = onnx_actions(paths["a"], obs[:1])
    many, targets = onnx_actions(paths["a"], obs[:3])
    assert one.shape == (1, 4) and many.shape == (3, 4)
    np.testing.assert_allclose(targets, default + 0.25 * many, atol=1e-6)
    other, _ = onnx_actions(paths["b"], obs[:3])
    assert np.abs(other - many).max() > 1e-3
    import onnx

    graph = onnx.load(str(paths["a"])).graph
    assert [i.name for i in graph.input] == ["obs"] and [o.name for o in graph.output] == [
        "actions",
        "joint_targets",
    ]


# -- a real Kuafu run ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def kuafu_handoff(tmp_path_factory):
    """A tiny co-adaptation run fine-tuned from the shipped flat policy (a few hundred PPO
    steps: it still walks), and its handoff folder with MuJoCo (and PyBullet when installed)
    evaluations at a tiny size."""
    if missing_deploy_modules():
        pytest.skip("needs the deploy extra (coadapt[deploy])")
    root = tmp_path_factory.mktemp("handoff_kuafu")
    args = [
        "run",
        "--optimizer",
        "pso",
        "--sim",
        "mujoco",
        "--objective",
        "torque",
        "--preset",
        "smoke",
        "--population",
        "3",
        "--agents-per-design",
        "2",
        "--eval-steps",
        "10",
        "--train-steps",
        "100",
        "--retrain-steps",
        "50",
        "--store",
        "none",
        "--out",
        str(root / "runs"),
        "--json",
    ]
    assert main(args) == 0
    run_dir = next((root / "runs").iterdir())
    out = root / "handoff"
    done = run_cli(
        "handoff",
        str(run_dir),
        "-o",
        str(out),
        "--agents",
        "2",
        "--seconds",
        "0.5",
        "--threads",  # both engines and torch on one thread (issue 61: it was refused)
        "1",
        "--json",
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return run_dir, out, json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


@pytest.mark.slow
def test_handoff_costs_say_their_protocol_and_no_library_banner(kuafu_handoff):
    """Issues 43 and 50: each simulator's evaluation says it follows the sim-to-sim protocol
    of `coadapt report`'s column and prints the protocol's line (the answer under the cost
    rule, the plain mean, the fall rates, the scenario count); PyBullet's import banner
    ("pybullet build time") is not printed."""
    stderr = kuafu_handoff[3]
    said = [
        line
        for line in stderr.splitlines()
        if line.startswith("evaluating the design and the nominal one")
    ]
    assert said and all(
        "(sim-to-sim protocol, as `coadapt report`'s column: 2 paired scenarios x 25 steps; "
        "not comparable with `coadapt run` or `coadapt eval`)" in x
        for x in said
    ), said
    costs = [
        line for line in stderr.splitlines() if "paired scenarios" in line and "plain mean" in line
    ]
    assert len(costs) == len(said) and all(
        "; plain mean " in x and "; fall rate " in x and "; 2 paired scenarios" in x for x in costs
    ), costs
    assert "pybullet build time" not in stderr


@pytest.mark.slow
def test_kuafu_handoff_folder_holds_models_controller_and_sheet(kuafu_handoff):
    import mujoco
    import torch

    from coadapt_core.handoff.run_info import sha256
    from coadapt_core.plugins import get_registry

    run_dir, out, result, stderr = kuafu_handoff
    for name in (
        "robot.xml",
        "robot.urdf",
        "policy.onnx",
        "policy.json",
        "design.json",
        "design.md",
        "README.md",
        "check.py",
        "reference.npz",
    ):
        assert (out / name).is_file(), name
    if (run_dir / "best_vs_nominal.gif").is_file():
        assert (out / "best_vs_nominal.gif").read_bytes() == (
            run_dir / "best_vs_nominal.gif"
        ).read_bytes()
    # ONNX against torch: printed, below the stated tolerance
    assert re.search(r"max \|action difference\| \d\.\d\de-\d\d \(tolerance 0\.0001\)", stderr)
    assert result["max_abs_action_difference"] <= ONNX_TOLERANCE == 1e-4
    summary = json.loads((run_dir / "summary.json").read_text())
    assert result["design"] == summary["best_design"] and result["is_run_best"] is True
    robot = get_registry().create("robot", "kuafu")
    model = robot.build(np.array(result["design"]))
    assert (out / "robot.xml").read_text() == model.text("mjcf")
    assert mujoco.MjModel.from_xml_path(str(out / "robot.xml")).nu == 8
    spec = json.loads((out / "policy.json").read_text())
    assert spec["observation"]["size"] == 70 == spec["observation"]["slices"][-1]["stop"]
    assert spec["action"]["joint_order"] == model.joint_names
    assert spec["joints"]["kp"] == pytest.approx(list(model.kp))
    assert spec["rates"]["control_dt"] == pytest.approx(0.02) and spec["rates"]["decimation"] == 4
    noise = {s["name"]: s["training_noise"] for s in spec["observation"]["slices"]}
    assert noise["joint_vel"]["scale"] == 1.5 and noise["command"] is None
    state = torch.load(run_dir / "checkpoints" / "backend-outer1.pt", weights_only=True)
    assert spec["commands"]["curriculum_limit"] == state["commands"]["limit"]
    sheet = json.loads((out / "design.json").read_text())
    assert sheet["body"]["total_mass"] == pytest.approx(model.total_mass, rel=1e-6)
    assert sheet["validation"]["feasible"] is True
    assert [p["unit"] for p in sheet["parameters"]] == ["x 0.35 m", "x 0.35 m"]
    prov = sheet["provenance"]
    assert prov["run_id"] == run_dir.name and prov["seed"] == 0
    assert prov["final_policy_sha256"] == sha256(run_dir / "checkpoints" / "backend-outer1.pt")
    assert prov["starting_policy_sha256"] == sha256(robot.shipped_policy("flat"))
    by_source = {(e["simulator"], e["source"].split(" (")[0]): e for e in sheet["evaluations"]}
    assert (
        by_source[("mujoco", "the run's final check")]["objectives"]["torque"]["design"]
        == summary["best_costs"]["torque"]
    )
    fresh = by_source[("mujoco", "evaluated by coadapt handoff")]
    row = fresh["objectives"]["torque"]
    assert np.isfinite([row["design"], row["nominal"], row["design_se"], row["improvement"]]).all()
    assert 0.0 <= fresh["design_fall_rate"] <= 1.0
    if "pybullet" in get_registry().names("simulator"):
        other = by_source[("pybullet", "evaluated by coadapt handoff")]
        assert "error" not in other and np.isfinite(other["objectives"]["torque"]["design"])
    text = (out / "design.md").read_text()
    assert (
        "## Validation: feasible" in text
        and "## Provenance" in text
        and prov["final_policy_sha256"] in text
    )


@pytest.mark.slow
def test_check_script_walks_the_design_without_coadapt(kuafu_handoff):
    """Done-when: the folder's script loads the MJCF, runs the ONNX controller for 10 s under
    0.5 m/s with every coadapt import refused, and the robot walks."""
    _, out, result, _ = kuafu_handoff
    tree = ast.parse((out / "check.py").read_text())
    imported = {
        a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
    }
    imported |= {
        n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module
    }
    assert not {m for m in imported if m.startswith("coadapt")}
    done = run_without_coadapt(out, "check.py", "--json")
    assert done.returncode == 0, done.stderr[-2000:]
    walked = json.loads(done.stdout.strip().splitlines()[-1])
    assert walked["seconds"] == 10.0 and walked["command"] == [0.5, 0.0, 0.0]
    assert walked["survival"] == 1.0 and walked["vx_mean"] >= 0.3, walked
    assert walked["onnx_vs_torch_max_abs_action_difference"] <= ONNX_TOLERANCE
    assert (
        result["controller_check"]["survival"] == 1.0
        and result["controller_check"]["vx_mean"] >= 0.3
    )
    plain = run_without_coadapt(out, "check.py")
    assert "survival 1.00" in plain.stdout and "mean forward speed" in plain.stdout


@pytest.mark.slow
def test_readme_snippet_runs_the_controller(kuafu_handoff):
    """The README's plain-Python example (at most 25 lines of at most 100 columns: 20 before the
    tree took a 100-column limit) loads the model and walks it."""
    _, out, _, _ = kuafu_handoff
    code = re.search(r"```python\n(.*?)```", (out / "README.md").read_text(), re.S).group(1)
    assert len(code.strip().splitlines()) <= 25
    (out / "snippet.py").write_text(code)
    done = run_without_coadapt(out, "snippet.py")
    assert done.returncode == 0, done.stderr[-2000:]
    x = float(re.search(r"base x after 10 s: (\S+)", done.stdout).group(1))
    assert x >= 3.0  # 0.3 m/s for 10 s


@pytest.mark.slow
@pytest.mark.parametrize("terrain", ["flat", "slope"])
def test_check_script_rebuilds_the_task_observation(kuafu_handoff, terrain):
    """Step for step, the script's observation equals the locomotion task's on the run's
    simulator (randomization and noise off, same command and clock, same spawn) under the
    same actions, on flat ground and on the slope."""
    import importlib.util

    import torch

    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.plugins import get_registry
    from coadapt_core.task.config import TaskConfig
    from coadapt_core.task.env import LocomotionEnv

    _, out, _, _ = kuafu_handoff
    loader = importlib.util.spec_from_file_location("handoff_check", out / "check.py")
    check = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(check)
    spec = json.loads((out / "policy.json").read_text())
    registry = get_registry()
    robot = registry.create("robot", "kuafu")
    design = np.array(list(spec["design"].values()))
    sim = registry.get("simulator", "mujoco")(
        robot, design[None], terrain=terrain, randomization=RandomizationConfig.off()
    )
    task = TaskConfig()
    task.noise.enabled = False
    env = LocomotionEnv(sim, robot, task, [], seed=0)
    env.set_commands(torch.tensor([[0.5, 0.0, 0.0]]))
    env.reset()
    env.phase[:] = 0.0
    expected = env._observe(env.state)[0].numpy()
    mine = check.Robot(spec, out, terrain)
    mine.reset()
    controller = check.Controller(spec, out / "policy.onnx", np.array([0.5, 0.0, 0.0]), 0.0)
    got = controller.observe(mine)
    worst = []
    for _ in range(25):
        worst.append(float(np.abs(expected - got).max()))
        actions, targets = controller.act(got)
        expected = env.step(torch.from_numpy(actions[None].copy())).obs.numpy()
        mine.step(targets.astype(np.float64))
        controller.advance(actions)
        got = controller.observe(mine)
    sim.close()
    assert worst[0] == 0.0 and max(worst) < 1e-4, worst


@pytest.mark.slow
def test_a_graph_that_differs_from_torch_is_refused_and_nothing_is_left(
    kuafu_handoff, tmp_path, monkeypatch, capsys
):
    from coadapt_core.handoff import policy as policy_module

    export = policy_module.export_onnx

    def wrong_export(policy, path, metadata):  # a graph whose last bias is off by 1e-3
        import torch

        with torch.no_grad():
            list(policy.parameters())[-1] += 1e-3  # the output layer's bias
        return export(policy, path, metadata)

    monkeypatch.setattr(policy_module, "export_onnx", wrong_export)
    run_dir, *_ = kuafu_handoff
    out = tmp_path / "refused"
    assert main(["handoff", str(run_dir), "-o", str(out), "--no-check"]) == 1
    err = capsys.readouterr().err
    assert "differs from the torch policy by 1.00e-03 > 0.0001" in err
    assert not out.exists() and not list(tmp_path.glob(".refused.partial-*"))


@pytest.mark.slow
def test_an_existing_folder_or_a_bad_design_is_one_line_exit_2(kuafu_handoff, capsys):
    run_dir, out, _, _ = kuafu_handoff
    assert main(["handoff", str(run_dir), "-o", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert (
        main(["handoff", str(run_dir), "-o", str(out.parent / "x"), "--design", "1.0,1.0,1.0"]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--design" in err[0]
    assert main(["handoff", str(run_dir), "-o", str(run_dir.parent)]) == 2
    assert "holds it" in capsys.readouterr().err


# -- the example plugin's quadruped -------------------------------------------------------------
@needs_deploy
@pytest.mark.slow
def test_handoff_of_the_example_quadruped(example_plugin_site, tmp_path):
    """A third-party robot's run hands off like Kuafu's: its MJCF and URDF, its joint order
    and trot clock in policy.json, ONNX parity, a design chosen with --design (not the run's
    best), and a check script that runs (a 2-iteration policy need not walk)."""
    import mujoco

    sys.path.insert(0, str(example_plugin_site))
    try:
        from coadapt_example.robot import Trotter
    finally:
        sys.path.remove(str(example_plugin_site))
    done = run_cli(
        "run",
        "--robot",
        "trotter",
        "--preset",
        "smoke",
        "--checkpoint",
        "none",
        "--population",
        "2",
        "--outer-iterations",
        "1",
        "--optimizer-iterations",
        "1",
        "--no-video",
        "--out",
        str(tmp_path / "runs"),
        "--store",
        "none",
        "--json",
        pythonpath=[example_plugin_site],
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    run_dir = next((tmp_path / "runs").iterdir())
    out = tmp_path / "trotter-handoff"
    done = run_cli(
        "handoff",
        str(run_dir),
        "-o",
        str(out),
        "--design",
        "1.2,0.9",
        "--sim",
        "mujoco",
        "--agents",
        "2",
        "--seconds",
        "0.5",
        "--no-video",
        "--json",
        pythonpath=[example_plugin_site],
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert (
        result["robot"] == "trotter"
        and result["design"] == [1.2, 0.9]
        and result["is_run_best"] is False
    )
    assert result["max_abs_action_difference"] <= ONNX_TOLERANCE
    model = Trotter().build(np.array([1.2, 0.9]))
    assert (out / "robot.xml").read_text() == model.text("mjcf") and (
        out / "robot.urdf"
    ).read_text() == model.text("urdf")
    assert mujoco.MjModel.from_xml_path(str(out / "robot.xml")).nu == 8
    spec = json.loads((out / "policy.json").read_text())
    assert spec["action"]["joint_order"] == model.joint_names
    assert [leg["phase_offset"] for leg in spec["gait"]["legs"]] == [0.0, 0.5, 0.5, 0.0]
    sheet = json.loads((out / "design.json").read_text())
    assert sheet["body"]["total_mass"] == pytest.approx(model.total_mass, rel=1e-6)
    assert [e["source"].split(" (")[0] for e in sheet["evaluations"]] == [
        "evaluated by coadapt handoff"
    ]
    assert "survival" in sheet["controller_check"]
    assert sheet["picture"].startswith("none")
    walked = run_without_coadapt(out, "check.py", "--seconds", "2", "--json")
    assert walked.returncode == 0, walked.stderr[-2000:]
    assert (
        json.loads(walked.stdout.strip().splitlines()[-1])[
            "onnx_vs_torch_max_abs_action_difference"
        ]
        <= ONNX_TOLERANCE
    )
