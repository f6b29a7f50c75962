"""xacro files: their expansion to URDF text, with ``$(find NAME)`` resolved through package
folders (the ones given, then ``ROS_PACKAGE_PATH``'s, then the file's own folder), and its
expressions evaluated as data (:mod:`hybrid_force.model.xacro_eval`) unless the file is trusted.
"""

from __future__ import annotations

import contextlib
import io
import os
import threading
import warnings
import xml.parsers.expat
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from hybrid_force.errors import ModelWarning, RobotError
from hybrid_force.model.urdf_check import check_urdf
from hybrid_force.model.urdf_text import check_file_size, check_model_size

__all__ = ["expand_xacro", "find_package", "xacro_argument_text"]

_XACRO_LOCK = threading.Lock()  # xacro keeps its state in module globals


def _absolute_dirs(dirs: Sequence[str | os.PathLike[str]]) -> tuple[str, ...]:
    """The package folders as absolute paths (a single text is refused: it is no list)."""
    if isinstance(dirs, (str, bytes, os.PathLike)):
        raise RobotError(f"package_dirs must be a list of folders, got the single value {dirs!r}")
    if not isinstance(dirs, Iterable):  # a number: not Python's "object is not iterable"
        raise RobotError(f"package_dirs must be a list of folders, got {dirs!r}")
    out = []
    for d in dirs:
        if not isinstance(d, (str, os.PathLike)) or not str(d):
            raise RobotError(f"package_dirs must hold folder paths, got {d!r}")
        out.append(os.path.abspath(d))  # absolute, ".." resolved (not symlinks)
    return tuple(out)


def _ros_package_path() -> tuple[str, ...]:
    """The folders of the ``ROS_PACKAGE_PATH`` environment variable, absolute, in order."""
    text = os.environ.get("ROS_PACKAGE_PATH", "")
    return tuple(os.path.abspath(d) for d in text.split(os.pathsep) if d)


def find_package(name: str, package_dirs: Sequence[str]) -> Path | None:
    """The folder ``NAME`` inside the first of ``package_dirs`` that holds one, else None.

    What ``package://NAME/...`` and xacro's ``$(find NAME)`` resolve against.
    """
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        return None
    for folder in package_dirs:
        candidate = Path(folder) / name
        if candidate.is_dir():
            return candidate
    return None


def expand_xacro(
    path: str | os.PathLike[str],
    args: Mapping[str, str],
    package_dirs: Sequence[str | os.PathLike[str]],
    *,
    check: bool = False,
    includes: list[str] | None = None,
    trust: bool = False,
) -> str:
    """The URDF text that the xacro file ``path`` expands to, with the arguments ``args``.

    ``$(find NAME)`` is the folder NAME in the first folder that holds one, of
    ``package_dirs``, then ``ROS_PACKAGE_PATH``'s, then the xacro file's own folder (xacro's
    own ``$(find)`` needs ROS 2's ament index, which is not used). Includes are read relative
    to the including file. What xacro prints as warnings becomes one :class:`ModelWarning`
    naming the file.

    Expanding a file never runs code it carries: every ``${...}`` and ``$(eval ...)``
    expression (also an include's file name, a property's or a macro parameter's value) is
    evaluated by :func:`~hybrid_force.model.xacro_eval.eval_expression` /
    :func:`~hybrid_force.model.xacro_eval.eval_substitution`, not by Python's ``eval``. Only
    with ``trust`` does xacro evaluate them itself, as Python with its builtins.

    Args:
        path: the ``.xacro`` file.
        args: ``{name: text}`` values of its ``<xacro:arg>`` (``$(arg name)``).
        package_dirs: folders that hold package folders (see :func:`load_robot`).
        check: also check the expansion as :func:`load_robot` does
            (:func:`~hybrid_force.model.urdf_check.check_urdf`; its messages and warnings name
            ``<path> (as expanded by xacro)``).
        includes: if given, the absolute paths of the files the expansion included (not
            ``path`` itself) are appended to it, also when it fails (those read until then):
            what a sweep hashes to know that its rows saw the same model.
        trust: let xacro evaluate the file's expressions as Python (the file's code runs).

    Raises:
        RobotError: the ``xacro`` package is missing, or xacro cannot expand the file (XML
            syntax, an undefined argument or property, a missing include, ``$(find NAME)``
            with no folder NAME); the message names the file (and the included file where it
            happened) and xacro's own message. With ``check``: an expansion that is not a
            URDF the toolkit can simulate. Without ``trust``: an expression outside the
            safe evaluator's allowlist (the message names the file, the expression and how
            to opt in).
    """
    path = Path(path)
    try:
        import xacro
        from xacro import substitution_args

        from hybrid_force.model.xacro_eval import (
            counted_macro_calls,
            eval_expression,
            eval_substitution,
        )
    except ImportError as exc:
        raise RobotError(
            f"cannot expand {path}: the 'xacro' package is missing ({exc}); pip install xacro"
        ) from None

    dirs = tuple(
        dict.fromkeys(
            (*_absolute_dirs(package_dirs), *_ros_package_path(), str(path.resolve().parent))
        )
    )

    def find(name: str) -> str:
        found = find_package(name, dirs)
        if found is None:
            raise RobotError(  # inside xacro, which wraps it: expand_xacro unwraps it
                f"$(find {name}): no folder '{name}' in the package folders "
                f"({', '.join(dirs) or 'none'}); add the folder that holds it to "
                "robot.package_dirs (load_robot's package_dirs) or ROS_PACKAGE_PATH"
            )
        return str(found)

    with contextlib.suppress(OSError):  # a missing file: xacro says so below
        check_file_size(path, "xacro file")
    said = io.StringIO()
    target = str(path.resolve())
    with _XACRO_LOCK, contextlib.redirect_stderr(said), contextlib.redirect_stdout(said):
        saved_find = getattr(substitution_args, "_eval_find", None)
        saved_eval = substitution_args._eval_dict.get("find")
        saved_safe_eval, saved_sub_eval = xacro.safe_eval, substitution_args._eval
        saved_macro_call = xacro.handle_macro_call
        try:
            substitution_args._eval_find = find
            substitution_args._eval_dict["find"] = find
            if not trust:  # xacro's two calls of Python's eval: ${...} and $(eval ...)
                xacro.safe_eval = lambda expr, symbols, _=None: eval_expression(expr, symbols)
                substitution_args._eval = eval_substitution
                # nested macros can double the document at each level: calls are bounded
                xacro.handle_macro_call = counted_macro_calls(saved_macro_call)
            xacro.all_includes = []  # xacro's record of every file it read: never emptied by it
            doc = xacro.process_file(target, mappings=dict(args), verbosity=0)
            text = doc.toxml()
        except Exception as exc:
            stack = [f for f in (getattr(xacro, "filestack", None) or []) if f]
            where = f" (in {stack[-1]})" if stack and stack[-1] != target else ""
            macros = getattr(xacro, "macrostack", None) or []
            if macros:
                with contextlib.suppress(Exception):
                    where += f" (in macro '{macros[-1].body.getAttribute('name')}')"
            cause: BaseException | None = exc  # xacro wraps our $(find) RobotError: unwrap it
            for _ in range(10):
                if cause is None or isinstance(cause, RobotError):
                    break
                cause = getattr(cause, "exc", None) or cause.__cause__ or cause.__context__
            cause = cause if isinstance(cause, RobotError) else None
            if isinstance(exc, xml.parsers.expat.ExpatError):
                why = f"XML syntax error: {exc}"
            elif cause is not None:
                why = str(cause)
            else:
                why = " ".join(str(exc).split()) or type(exc).__name__
            raise RobotError(f"xacro cannot expand {path}{where}: {why}") from None
        finally:
            if includes is not None:
                includes.extend(str(f) for f in getattr(xacro, "all_includes", None) or [])
            xacro.safe_eval, substitution_args._eval = saved_safe_eval, saved_sub_eval
            xacro.handle_macro_call = saved_macro_call
            if saved_find is not None:
                substitution_args._eval_find = saved_find
            if saved_eval is not None:
                substitution_args._eval_dict["find"] = saved_eval
    messages = [" ".join(x.split()) for x in said.getvalue().splitlines() if x.strip()]
    if messages:
        warnings.warn(f"{path}: xacro reported: {'; '.join(messages)}", ModelWarning, stacklevel=3)
    check_model_size(f"{path} (as expanded by xacro)", text, "urdf")
    if check:
        _check_urdf_text(path, text, expanded=True)
    return text


def _check_urdf_text(path: Path, xml: str, *, expanded: bool) -> None:
    """:func:`~hybrid_force.model.urdf_check.check_urdf` on the URDF text of ``path``; for xacro's
    expansion (``expanded``) its messages say ``<path> (as expanded by xacro)``."""

    if not expanded:
        check_urdf(path, text=xml)
        return
    shown = f"{path} (as expanded by xacro)"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ModelWarning)
        try:
            check_urdf(path, text=xml)
        except RobotError as exc:
            raise RobotError(str(exc).replace(str(path), shown, 1)) from None
    for w in caught:
        message = str(w.message)
        if issubclass(w.category, ModelWarning):
            message = message.replace(str(path), shown, 1)
        warnings.warn(message, w.category, stacklevel=4)


def xacro_argument_text(value: object) -> str:
    """The text a ``robot.xacro_args`` value passes to xacro: a string as is, a boolean as
    ``true``/``false``, an integer in decimal, a float as Python's shortest repr (``0.7``)."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    raise TypeError(f"a xacro argument must be a string, number or boolean, got {value!r}")
