"""Sphinx configuration of the API reference (``make docs``; sources in docs/api/).

The module tree is not written here: autosummary walks the packages named in
index.rst (``:recursive:``) and writes one page per module into ``generated/``
(rebuilt on every ``make docs``, ignored by git), so a module moved or renamed
is documented where it now lives without touching these files.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import pkgutil
import sys
import types
from pathlib import Path

from sphinx.ext import autosummary
from sphinx.ext.autosummary import generate as autosummary_generate_module
from sphinx.util import logging

logger = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))  # the checkout being documented, installed editable or not

project = "seqdesign"
author = "the seqdesign authors"
copyright = "the seqdesign authors"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
]

templates_path = ["_templates"]
exclude_patterns = ["_build"]

# One page per module, written from the packages themselves.
autosummary_generate = True
autosummary_generate_overwrite = True
autosummary_imported_members = False

autodoc_default_options = {
    "members": True,
    "undoc-members": True,  # a public name without a docstring is listed too, not hidden
    # Each object is documented once, in the module that defines it; a package's ``__all__``
    # (its public face, mostly re-exports) is listed on its page as links (see _public_face).
    "ignore-module-all": True,
    "show-inheritance": True,
    "member-order": "bysource",
}
# Type hints are shown in the signature only (the numpydoc sections already say what each
# parameter is); ``from __future__ import annotations`` keeps them as written.
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
autodoc_class_signature = "mixed"

# numpydoc-style docstrings.
napoleon_google_docstring = False
napoleon_numpy_docstring = True
# Parameter types as written (``(n, 3) array``), not cross-references to whatever is named n.
napoleon_use_param = False
napoleon_use_keyword = False
napoleon_use_rtype = False
napoleon_use_ivar = True

# -n (nitpicky): every cross-reference must resolve. Names of other projects (numpy, the
# standard library, networkx, casadi, click) are not documented here and there is no
# intersphinx (the build runs offline): they are the one thing let through, by their package.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|pathlib|os|collections|typing|networkx|casadi|click|rerun|dask)(\..+)?"),
]

html_theme = "alabaster"
html_title = "seqdesign API reference"
html_static_path: list[str] = []


# ``python -m pkg`` entry modules run the program when imported, and autosummary imports every
# module it walks (even the private ones it then leaves out): each ``__main__.py`` of the
# packages is replaced by an empty placeholder so that building the docs runs no command.
# They are found by walking the tree, not named here.
for _main in sorted(REPO.glob("*/**/__main__.py")):
    _name = ".".join(_main.relative_to(REPO).with_suffix("").parts)
    if _name.split(".")[0] in {"calib", "seqdesign", "viz"}:
        sys.modules[_name] = types.ModuleType(_name, "placeholder: ``python -m`` entry, not imported")


def _defined_in(module: types.ModuleType, name: str) -> str | None:
    """The module that defines ``name`` (follows ``from X import name`` re-exports), or None."""
    obj = getattr(module, name, None)
    if isinstance(obj, types.ModuleType):
        return obj.__name__
    if getattr(obj, "__module__", None) and getattr(obj, "__qualname__", None):
        return f"{obj.__module__}.{obj.__qualname__}"
    try:
        tree = ast.parse(inspect.getsource(module))
    except (OSError, TypeError):
        return None
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    package = module.__name__ if hasattr(module, "__path__") else module.__package__
                    relative = "." * node.level + (node.module or "")
                    source = importlib.util.resolve_name(relative, package) if node.level else relative
                    return _defined_in(importlib.import_module(source), alias.name)
        targets = (
            node.targets
            if isinstance(node, ast.Assign)
            else [node.target]
            if isinstance(node, ast.AnnAssign)
            else []
        )
        if any(isinstance(t, ast.Name) and t.id == name for t in targets):
            return f"{module.__name__}.{name}"
    return None


def _public_face(app, what, name, obj, options, lines):
    """A module's ``__all__``, listed under its docstring with links to where each name lives."""
    if what != "module" or not isinstance(getattr(obj, "__all__", None), list | tuple):
        return
    lines += ["", ".. rubric:: Public names (``__all__``)", ""]
    for public in obj.__all__:
        where = _defined_in(obj, public)
        if where is None or where == f"{name}.{public}":
            lines.append(f"- :py:obj:`{public} <{name}.{public}>`" if where else f"- ``{public}``")
        else:
            lines.append(f"- :py:obj:`{public} <{where}>` (from ``{where.rsplit('.', 1)[0]}``)")
    lines.append("")


def _types_as_text(app, what, name, obj, options, lines):
    """An attribute's numpydoc type (``ndarray, shape (K - 1, 3)``) shown as written.

    The types of the docstrings are prose, not annotations: napoleon renders the parameters'
    as text (``napoleon_use_param = False``) and this does the same for the attributes'
    (``:vartype:``), so that ``shape``, ``3`` or ``n`` are not looked up as classes. The
    signatures keep their annotations as links.
    """
    for i, line in enumerate(lines):
        head, sep, kind = line.partition(": ")
        if head.startswith(":vartype ") and sep and kind.strip() and not set(kind) & set("*`|"):
            lines[i] = f"{head}: *{kind.strip()}*"


def _public_alias(app, env, node, contnode):
    """Resolve a reference that Sphinx's own lookup missed, to the one place it can mean.

    - ``calib.runlog.read_run`` (a package's public face) and a module's imported names
      (``:func:`map_jobs``` in a module that imports it): documented once, where they are
      defined, and linked there;
    - a constant or a private helper the module defines (``:data:`TRIM_S```): linked to
      its module's page (autodoc documents no undocumented constant);
    - a short name met outside its module (a module's summary in its package's table):
      linked if exactly one documented object has that name.

    Anything else (a name that no longer exists, two candidates) stays unresolved and fails
    the build.
    """
    if node.get("refdomain") != "py":
        return None
    domain = env.get_domain("py")
    target = node["reftarget"].removeprefix("~").removeprefix(".")
    context = node.get("py:module")

    def resolve(reftype, name):
        new = node.deepcopy()
        new["reftarget"], new["refspecific"] = name, False
        return domain.resolve_xref(env, node["refdoc"], app.builder, reftype, name, new, contnode)

    for dotted in [target] + ([f"{context}.{target}"] if context else []):
        module_name, _, attr = dotted.rpartition(".")
        if module_name not in sys.modules or not attr:
            continue
        where = _defined_in(sys.modules[module_name], attr)
        if where is None:
            continue
        found = resolve(node["reftype"], where) or resolve("obj", where)
        found = found or resolve("mod", where.rpartition(".")[0])
        if found is not None:
            return found
    matches = domain.find_obj(env, None, None, target, None, 1)
    if len({name for name, _ in matches}) == 1:
        return resolve("obj", matches[0][0])
    return None


def _keep_attribute_summary(app, what, name, obj, options, lines):
    """A property's or attribute's summary kept as written (``Sort key: best ratio first``).

    napoleon reads ``WORDS: text`` on the first line of an attribute's docstring as a type and
    its description; the house style is a summary and its detail, so the line is put back.
    """
    if what not in ("attribute", "property", "data"):
        return
    first = (inspect.getdoc(obj) or "").partition("\n")[0]
    for i, line in enumerate(lines):
        if line.startswith(":type: ") and first.startswith(line[len(":type: ") :] + ":"):
            del lines[i]
            body = [j for j, text in enumerate(lines) if text.strip()]
            if body:
                lines[body[0]] = first
            break


def _module_first(import_by_name):
    """The import of autosummary, but a submodule is the module even if its package shadows it.

    ``seqdesign.search.design`` is a module, and ``design`` the function its package
    re-exports: autosummary would document the function under the module's name and leave
    the module out. (The build also checks that no module was left out: _all_documented.)
    """

    def shadowed_module(full):
        parent, _, last = full.rpartition(".")
        if not parent or parent not in sys.modules:
            return None
        try:
            spec = importlib.util.find_spec(full)
        except (ImportError, ValueError):
            return None
        if spec is None:
            return None
        module = importlib.import_module(full)
        return module if getattr(sys.modules[parent], last, module) is not module else None

    def wrapped(name, prefixes=(None,), *args, **kwargs):
        for prefix in prefixes:
            full = f"{prefix}.{name}" if prefix else name
            module = shadowed_module(full)
            if module is not None:
                return full, module, sys.modules[full.rpartition(".")[0]], full
        return import_by_name(name, prefixes, *args, **kwargs)

    return wrapped


autosummary.import_by_name = _module_first(autosummary.import_by_name)
autosummary_generate_module.import_by_name = _module_first(autosummary_generate_module.import_by_name)


def _walked_modules() -> set[str]:
    """Every module of the three packages, by walking them (what the reference must hold)."""
    names = set()
    for package in ("calib", "seqdesign", "viz"):
        names.add(package)
        path = importlib.import_module(package).__path__
        for info in pkgutil.walk_packages(path, prefix=f"{package}."):
            if not any(part.startswith("_") for part in info.name.split(".")):
                names.add(info.name)
    return names


def _all_documented(app, env):
    """Fail the build if a module of the packages has no page (nothing left out silently)."""
    documented = set(env.get_domain("py").modules)
    for name in sorted(_walked_modules() - documented):
        logger.warning("module %s is in the packages but not in the API reference", name)


def _dataclass_factories(app, what, name, obj, options, signature, return_annotation):
    """A dataclass field's ``<factory>`` default written as the call (``dict()``).

    ``<factory>`` (what :func:`inspect.signature` shows) is no Python: Sphinx cannot parse
    the signature and splits it at every comma, so ``dict[str, int]`` became two names.
    """
    fields = getattr(obj, "__dataclass_fields__", None)
    if not signature or "<factory>" not in signature or fields is None:
        return None
    for field in fields.values():
        factory = field.default_factory
        if field.init and callable(factory) and "<factory>" in signature:
            call = f"{getattr(factory, '__qualname__', '...')}()".replace("<lambda>()", "...")
            signature = signature.replace("<factory>", call, 1)
    return signature.replace("<factory>", "..."), return_annotation


def setup(app):
    """The hooks above, in the order they act."""
    app.connect("autodoc-process-signature", _dataclass_factories)
    app.connect("env-check-consistency", _all_documented)
    app.connect("autodoc-process-docstring", _public_face)
    # after napoleon (priority 500) has turned the numpydoc sections into fields
    app.connect("autodoc-process-docstring", _types_as_text, priority=600)
    app.connect("autodoc-process-docstring", _keep_attribute_summary, priority=600)
    app.connect("missing-reference", _public_alias)
