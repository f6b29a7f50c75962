"""A model file is data: expanding a xacro file, checking, running or replaying it never runs
code it carries (issue 27); ``robot.xacro_trust`` / ``--trust-xacro`` opt in to xacro's own
evaluation.

Each hostile payload writes a marker file if its code runs: the tests assert the marker is not
on disk, the error (exit status 2) names the file and the expression, and nothing was written.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import pytest
from conftest import ROD_MACRO, RTR_XACRO

from hybrid_force.cli import main
from hybrid_force.errors import RobotError, ScenarioError
from hybrid_force.model.loading import load_robot
from hybrid_force.model.xacro_eval import eval_expression
from hybrid_force.model.xacro_files import expand_xacro
from hybrid_force.result import Result
from hybrid_force.scenario.loader import load_scenario

# An escape that passes xacro's own guard (no "__" in the text): a property's text handed to
# $(eval), whose Python eval has the real builtins; the escapes hide "__" and the parentheses.
_EXEC = r"exec('\x5f\x5fimport\x5f\x5f\x28\x22os\x22\x29.system\x28\x22touch {m}\x22\x29')"
# An escape through xacro's ${} namespaces: a function's globals (the xacro module's, holding
# os) reached with vars() and string keys, never a "__" name.
_GLOBALS = (
    "python.vars(python.type(xacro.load_yaml))['\\x5f\\x5fglobals\\x5f\\x5f']"  # the descriptor
)
_VARS_CHAIN = (
    "${python.vars(python.type(" + _GLOBALS + "))['\\x5f\\x5fget\\x5f\\x5f']"
    "(" + _GLOBALS + ", xacro.load_yaml)['os'].system('touch {m}')}"
)

#: (id, extra xacro lines before the world link, the world link's attribute value, a piece of
#: the expression the message must show)
PAYLOADS: list[tuple[str, str, str, str]] = [
    ("eval-import", "", "$(eval __import__('os').system('touch {m}'))", "__import__('os'"),
    ("expr-import", "", '${__import__("os").system("touch {m}")}', '__import__("os")'),
    ("escaped-exec", f'<xacro:property name="p" value="{_EXEC}"/>', "$(eval ${p})", "exec("),
    ("escaped-in-expr", "", "${" + _EXEC + "}", "exec("),
    ("vars-chain", "", _VARS_CHAIN, "python.vars("),
    ("class-attr", "", "${(1).__class__}", "(1).__class__"),
    ("str-join", "", "${''.join(['a', 'b'])}", "''.join("),
    ("base-class", "", "${[].__class__.__base__}", "[].__class__"),
    ("open", "", "${open('{m}', 'w')}", "open("),
    ("exec", "", "${exec('open(1)')}", "exec("),
    ("eval", "", "${eval('1')}", "eval("),
    ("getattr", "", "${getattr(1, 'real')}", "getattr("),
    ("globals", "", "${globals()}", "globals()"),
    ("lambda", "", "${(lambda: 1)()}", "lambda"),
    ("comprehension", "", "${[x for x in [1, 2]]}", "for x in"),
    ("huge-power", "", "${9**9**9}", "9**9**9"),
    ("huge-text", "", "${'a' * 10**9}", "'a' * 10**9"),
    ("huge-format", "", "${'%999999999d' % 1}", "%999999999d"),
    ("nested-repeat", "", "${str([[0] * 99999] * 99999)}", "str([[0] * 99999]"),
    ("huge-round", "", "${round(5, -10**12)}", "round(5, -10**12)"),
    ("eval-builtin", "", "$(eval open)", "open"),
]


def _write(folder: Path, extra: str, value: str, marker: Path) -> Path:
    """folder/arm.urdf.xacro: the RTR with the payload (and folder/parts/rod.xacro)."""
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "rod.xacro").write_text(ROD_MACRO)
    attr = quoteattr(value.replace("{m}", str(marker)))
    lines = f'{extra.replace("{m}", str(marker))}\n<link name="world" note={attr}/>'
    text = RTR_XACRO.replace('<link name="world"/>', lines)
    path = folder / "arm.urdf.xacro"
    path.write_text(text)
    return path


def _assert_refused(message: str, path: Path, piece: str) -> None:
    """The one-line message names the file, the expression, and how to opt in."""
    assert str(path) in message
    assert f"the expression '{piece}" in message or piece in message.split("the expression")[1]
    assert "robot.xacro_trust = true" in message and "--trust-xacro" in message


@pytest.mark.parametrize(
    ("extra", "value", "piece"), [p[1:] for p in PAYLOADS], ids=[p[0] for p in PAYLOADS]
)
def test_load_robot_refuses_the_payload_without_running_it(
    tmp_path: Path, extra: str, value: str, piece: str
) -> None:
    marker = tmp_path / "PWNED"
    path = _write(tmp_path, extra, value, marker)
    with pytest.raises(RobotError) as info:
        load_robot(path)
    assert not marker.exists()
    _assert_refused(" ".join(str(info.value).split()), path, piece)


def test_xacro_is_left_as_it_was(tmp_path: Path) -> None:
    """The hook is undone after a refusal: xacro's own evaluation is back (and still unsafe)."""
    import xacro
    from xacro import substitution_args

    saved = (xacro.safe_eval, substitution_args._eval)
    path = _write(tmp_path, "", "${open('x')}", tmp_path / "m")
    with pytest.raises(RobotError):
        expand_xacro(path, {}, [])
    assert (xacro.safe_eval, substitution_args._eval) == saved


def test_an_included_file_named_by_an_expression_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "PWNED"
    include = f"<xacro:include filename=\"${{__import__('os').system('touch {marker}')}}\"/>"
    path = _write(tmp_path, include, "x", marker)
    with pytest.raises(RobotError, match=r"contains a double underscore"):
        load_robot(path)
    assert not marker.exists()
    # a file name made of properties is ordinary data
    good = _write(tmp_path / "g", "", "x", marker)
    named = '<xacro:property name="d" value="parts"/><xacro:include filename="${d}/rod.xacro"/>'
    good.write_text(good.read_text().replace('<xacro:include filename="parts/rod.xacro"/>', named))
    assert load_robot(good).nv == 3


def test_trust_lets_xacro_run_the_file(tmp_path: Path) -> None:
    """With trust, xacro evaluates as Python: the escape runs (so the payloads are real), and
    a benign method call works."""
    marker = tmp_path / "PWNED"
    path = _write(tmp_path, f'<xacro:property name="p" value="{_EXEC}"/>', "$(eval ${p})", marker)
    load_robot(path, xacro_trust=True)
    assert marker.exists()
    benign = _write(tmp_path / "b", "", "x", marker)
    benign.write_text(benign.read_text().replace('name="link3"', "name=\"${'LINK3'.lower()}\""))
    with pytest.raises(
        RobotError, match=r"the expression ''LINK3'.lower\(\)' reads the attribute 'lower'"
    ):
        load_robot(benign)
    assert load_robot(benign, xacro_trust=True).nv == 3
    fmt = '<xacro:property name="f" value="\'{}\'.format(2 * 3)"/>'
    evaluated = _write(tmp_path / "e", fmt, "$(eval ${f})", marker)
    assert 'note="6"' in expand_xacro(evaluated, {}, [], trust=True)
    with pytest.raises(RobotError, match=r"reads the attribute 'format'"):
        expand_xacro(evaluated, {}, [])


BENIGN = """\
<?xml version="1.0"?>
<robot name="benign" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="prefix" default="arm"/>
  <xacro:arg name="scale" default="2"/>
  <xacro:property name="l" value="0.5"/>
  <xacro:property name="half" value="${l / 2}"/>
  <xacro:property name="names" value="${['a', 'b', 'c']}"/>
  <xacro:property name="pre" value="$(arg prefix)"/>
  <xacro:macro name="rod" params="name size:=1 mass:=^|2 *origin">
    <link name="${pre}_${name}">
      <inertial><xacro:insert_block name="origin"/><mass value="${mass * size}"/>
        <inertia ixx="${mass * size**2 / 12}" iyy="${-size if size > 10 else size}" izz="0"
                 ixy="0" ixz="0" iyz="0"/></inertial>
    </link>
  </xacro:macro>
  <xacro:rod name="base" size="${half}"><origin xyz="0 0 ${half}"/></xacro:rod>
  <xacro:if value="${l > 0.1 and not l > 1}">
    <link name="yes" a="${pi / 2}" b="${radians(90)}" c="${math.pi}" d="${'%s_x' % pre}"
          e="$(eval 2 * 3)" f="${names[1]}" g="${max(1, 2)}" h="${2**10}" i="${1 / 3}"
          j="${sqrt(2) * cos(0.3)}" k="${int(7.9)} ${str(3)} ${len(names)}"
          m="$(eval scale * 1.5)" n="${atan2(1, 2)} ${degrees(pi)} ${fabs(-l) if True else 0}"
          o="${xacro.arg('prefix')}_${python.min(3, 4)} ${names[0:2]} ${'x' in names}"/>
  </xacro:if>
  <xacro:unless value="${l > 0.1}"><link name="no"/></xacro:unless>
  <xacro:property name="n" value="3" lazy_eval="false"/>
  <link name="last" note="${n + 1} $(arg scale) ${'q' * 3} ${1e3} ${-(-4) // 3} ${7 % 4}"
        env="$(optenv HYBRID_FORCE_UNSET_VARIABLE fallback) $(env HYBRID_FORCE_XACRO_TEST)"/>
</robot>
"""


@pytest.mark.parametrize("args", [{}, {"prefix": "left", "scale": "4"}])
def test_ordinary_xacro_expands_as_xacro_expands_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: dict[str, str]
) -> None:
    """Math, properties, macros with parameters and blocks, conditionals and $(eval): the safe
    evaluator's expansion equals xacro's own (Python eval), the independent reference."""
    import xacro

    monkeypatch.setenv("HYBRID_FORCE_XACRO_TEST", "from-env")
    path = tmp_path / "benign.xacro"
    path.write_text(BENIGN)
    ours = expand_xacro(path, args, [])
    reference = xacro.process_file(str(path.resolve()), mappings=dict(args)).toxml()
    assert ours == reference
    assert 'a="1.5707963267948966"' in ours and 'e="6"' in ours and "fallback from-env" in ours


def test_namespaces_yaml_and_dynamic_calls_expand_as_xacro_expands_them(tmp_path: Path) -> None:
    """An include's namespace (ns.name, ns['name'], ns.macro), xacro.load_yaml with a unit
    tag and dotted access, xacro:call: equal to xacro's own expansion."""
    import xacro

    (tmp_path / "cfg.yaml").write_text(
        "arm:\n  length: 0.4\n  angle: !degrees 90\n  names: [a, b]\n"
    )
    (tmp_path / "inc.xacro").write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="w" value="0.3"/>'
        '<xacro:macro name="m" params="v"><link name="inc_${v}"/></xacro:macro></robot>'
    )
    path = tmp_path / "ns.xacro"
    path.write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:include filename="inc.xacro" ns="parts"/>'
        '<xacro:property name="cfg" value="${xacro.load_yaml(\'cfg.yaml\')}"/>'
        '<xacro:parts.m v="${parts.w * 2}"/>'
        '<link name="a" l="${cfg[\'arm\'][\'length\']}" m="${cfg.arm.length}" '
        'n="${cfg.arm.angle}" o="${cfg.arm.names[1]}" p="${parts[\'w\']}"/>'
        '<xacro:call macro="parts.m" v="x"/></robot>'
    )
    ours = expand_xacro(path, {}, [])
    assert ours == xacro.process_file(str(path.resolve())).toxml()
    assert 'n="1.5707963267948966"' in ours and '<link name="inc_0.6"/>' in ours


def test_the_bounds_are_not_in_the_way_of_ordinary_numbers() -> None:
    table: dict[str, object] = {}
    assert eval_expression("2**4000 > 0", table) is True
    assert eval_expression("'ab' * 1000", table) == "ab" * 1000
    assert eval_expression("10.0**300", table) == 1e300
    with pytest.raises(RobotError, match="more than 4096 bits"):
        eval_expression("2**5000", table)
    with pytest.raises(NameError, match="name 'nope' is not defined"):
        eval_expression("nope + 1", table)  # an ordinary mistake: xacro's own message
    with pytest.raises(ZeroDivisionError):
        eval_expression("1 / 0", table)


def test_a_macro_bomb_is_refused(tmp_path: Path) -> None:
    """Macros calling macros twice, 30 deep (2**30 links): refused after MAX_MACRO_CALLS."""
    from hybrid_force.model.xacro_eval import MAX_MACRO_CALLS

    body = ['<xacro:macro name="m0"><link name="x"/></xacro:macro>']
    body += [
        f'<xacro:macro name="m{i}"><xacro:m{i - 1}/><xacro:m{i - 1}/></xacro:macro>'
        for i in range(1, 30)
    ]
    path = tmp_path / "bomb.xacro"
    path.write_text(
        '<robot name="b" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        f"{''.join(body)}<xacro:m29/></robot>"
    )
    with pytest.raises(RobotError, match=rf"{path}.*more than {MAX_MACRO_CALLS} macro calls"):
        load_robot(path)
    with pytest.raises(RobotError, match=r"rounds to -1000000000000 digits"):
        eval_expression("round(5, -10**12)", {})


# --- the command line ------------------------------------------------------------------------
CLI_PAYLOADS = [p for p in PAYLOADS if p[0] in ("escaped-exec", "vars-chain", "open")]


@pytest.mark.parametrize(
    ("extra", "value", "piece"), [p[1:] for p in CLI_PAYLOADS], ids=[p[0] for p in CLI_PAYLOADS]
)
def test_robots_check_refuses_the_payload(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, value: str, piece: str
) -> None:
    marker = tmp_path / "PWNED"
    path = _write(tmp_path, extra, value, marker)
    assert main(["robots", "--check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: xacro cannot expand")
    _assert_refused(err[0], path, piece)
    assert not marker.exists()
    if value.startswith("$(eval ${"):  # the escape: with the opt-in, xacro runs it
        main(["robots", "--check", str(path), "--trust-xacro"])
        assert marker.exists()


SCENARIO = """\
name = "xacro_trust"
[robot]
model = "arm/arm.urdf.xacro"
{robot}
[surface]
type = "cylinder"
radius = 0.4
[trajectory]
type = "helix"
center = [0.0, 0.0, 10.0]
radius = 0.4
omega = 1.0
rise = 0.1
[initial]
tip = [0.4, 0.0, 7.0]
seed = [0.0, 6.0, 2.0]
[control]
supervisor = false
[sim]
duration = 0.02
"""


@pytest.mark.parametrize(
    ("extra", "value", "piece"), [p[1:] for p in CLI_PAYLOADS], ids=[p[0] for p in CLI_PAYLOADS]
)
def test_run_refuses_the_payload_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, value: str, piece: str
) -> None:
    marker = tmp_path / "PWNED"
    path = _write(tmp_path / "arm", extra, value, marker)
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(robot=""))
    out = tmp_path / "out"
    assert main(["run", str(scen), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f'error: {scen}: robot.model = "arm/arm.urdf.xacro": xacro cannot')
    _assert_refused(err[0], path, piece)
    assert not marker.exists()
    assert not (out / "result.npz").exists() and not (out / "summary.json").exists()


def test_the_scenario_key_and_its_type(tmp_path: Path) -> None:
    marker = tmp_path / "PWNED"
    _write(tmp_path / "arm", "", "x", marker)
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(robot='xacro_trust = "yes"'))
    with pytest.raises(ScenarioError) as info:
        load_scenario(scen)
    assert str(info.value).startswith(f'{scen}: robot.xacro_trust = "yes": ')
    scen.write_text(SCENARIO.format(robot="xacro_trust = true"))
    arm = tmp_path / "arm" / "arm.urdf.xacro"
    arm.write_text(arm.read_text().replace('name="link3"', "name=\"${'LINK3'.lower()}\""))
    assert load_scenario(scen).robot.nv == 3
    scen.write_text(SCENARIO.format(robot=""))
    with pytest.raises(ScenarioError, match=r"robot.model = \"arm/arm.urdf.xacro\": .*'lower'"):
        load_scenario(scen)
    assert load_scenario(scen, {"robot.xacro_trust": True}).robot.nv == 3  # as --trust-xacro


# --- result files and the replay -------------------------------------------------------------
def _result_file(
    folder: Path, robot_meta: dict[str, object], nq: int = 3, scenario: object = None
) -> Path:
    """A short hand-made result of an nq-joint arm whose meta["robot"] is ``robot_meta``
    (and meta["scenario"] ``scenario``)."""
    from hybrid_force.geometry.builtin_surfaces import Plane

    t = np.arange(11) * 0.01
    q = np.column_stack([0.1 * np.sin(t + j) + (5.0 if j == 1 else 0.0) for j in range(nq)])
    z = np.zeros_like(t)
    p = np.zeros((t.size, 3))
    meta = {
        "name": "xacro_trust",
        "robot": robot_meta,
        "scenario": scenario,
        "surfaces": [Plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).to_dict()],
        "events": [],
        "status": "ok",
    }
    result = Result(
        t=t, q=q, v=np.gradient(q, t, axis=0), q_d=q, u=np.zeros_like(q), p=p, p_d=p, f=z,
        f_d=z, phi=z, V=z, phase=np.zeros(t.size, dtype=np.int64), meta=meta,
    )  # fmt: skip
    return result.save(folder / "result.npz")


@pytest.mark.parametrize(
    ("extra", "value", "piece"), [p[1:] for p in CLI_PAYLOADS], ids=[p[0] for p in CLI_PAYLOADS]
)
def test_replay_never_expands_the_xacro_file_named_in_meta(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, value: str, piece: str
) -> None:
    pytest.importorskip("meshcat")
    marker = tmp_path / "PWNED"
    hostile = _write(tmp_path / "arm", extra, value, marker)
    # the result's own scenario claims trust: a result file never grants it
    table = {"model": "arm/arm.urdf.xacro", "xacro_trust": True}
    robot_meta = {"model": str(hostile), "tip": "tip", "nq": 3, "xacro_trust": True}
    old = _result_file(tmp_path, robot_meta, scenario={"robot": table})
    page = tmp_path / "replay.html"
    assert main(["replay", str(old), "--html", str(page)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(hostile) in err[0] and "does not store its expansion" in err[0]
    assert not marker.exists() and not page.exists()


def test_a_run_stores_the_expansion_and_the_replay_uses_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], write_xacro_rtr: Callable[[Path], Path]
) -> None:
    """``run`` stores the URDF text xacro's expansion gave; replaying after the xacro file was
    replaced by a hostile one builds the arm from that text: the file is not expanded."""
    pytest.importorskip("meshcat")
    arm = write_xacro_rtr(tmp_path / "arm")
    arm.rename(tmp_path / "arm" / "arm.urdf.xacro")
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(robot=""))
    out = tmp_path / "out"
    assert main(["run", str(scen), "--out", str(out), "--quiet"]) == 0
    meta = json.loads(str(np.load(out / "result.npz")["meta"]))
    expected = expand_xacro(tmp_path / "arm" / "arm.urdf.xacro", {}, [])
    assert meta["robot"]["model_text"] == expected and meta["robot"]["model_format"] == "urdf"
    assert "xacro_trust" not in meta["robot"]  # a result file never grants trust
    marker = tmp_path / "PWNED"
    _write(tmp_path / "arm", f'<xacro:property name="p" value="{_EXEC}"/>', "$(eval ${p})", marker)
    page = tmp_path / "replay.html"
    assert main(["replay", str(out / "result.npz"), "--html", str(page)]) == 0
    assert page.stat().st_size > 0 and not marker.exists()
    capsys.readouterr()


def test_replay_of_an_old_urdf_result_reads_the_urdf_as_data(tmp_path: Path) -> None:
    """Without a stored text, a plain URDF file is read again (no expansion of any kind)."""
    pytest.importorskip("meshcat")
    from hybrid_force.viz.scene import Replay

    rtr = Path(__file__).resolve().parents[1] / "robots" / "rtr.urdf"
    old = _result_file(tmp_path, {"model": str(rtr), "tip": "tip", "nq": 3})
    assert Replay(old).robot.nv == 3
    assert os.listdir(tmp_path) == ["result.npz"]


# --- sweep and compare -----------------------------------------------------------------------
@pytest.mark.parametrize("command", ["sweep", "compare"])
def test_sweep_and_compare_refuse_the_payload_and_trust_on_request(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    marker = tmp_path / "PWNED"
    path = _write(
        tmp_path / "arm", f'<xacro:property name="p" value="{_EXEC}"/>', "$(eval ${p})", marker
    )
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(robot=""))
    out = tmp_path / "out"
    options = ["--grid", "sim.duration=0.02"] if command == "sweep" else ["--laws", "raibert_craig"]
    argv = [command, str(scen), *options, "--out", str(out), "--workers", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "the expression 'exec(" in err and "--trust-xacro" in err
    assert not marker.exists() and not list(out.rglob("*.csv")) and not list(out.rglob("*.npz"))
    # a file that needs trust for a method call: refused, then expanded with --trust-xacro
    _write(tmp_path / "arm", "", "x", marker)
    path.write_text(path.read_text().replace('name="link3"', "name=\"${'LINK3'.lower()}\""))
    assert main([*argv, "--trust-xacro"]) == 0, capsys.readouterr().err
    assert list(out.rglob("*.csv"))
    assert command == "sweep" or list(out.rglob("*.npz"))
    for kept in out.rglob("*.npz"):  # compare keeps its runs: the expansion, not the file
        robot_meta = json.loads(str(np.load(kept)["meta"]))["robot"]
        assert robot_meta["model"] == str(path.resolve())
        assert 'name="link3"' in robot_meta["model_text"] and "xacro_trust" not in robot_meta
