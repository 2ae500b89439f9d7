"""The native half of simnet (Rust, pyo3). Use the functions of `simnet` itself; these are what they call."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

class ScenarioError(ValueError):
    """A scenario or option simnet refuses."""

    message: str
    """What the command line prints."""
    key: Optional[str]
    """The first key at fault (`consensus.gate`, `loss_model`), None when the whole file is."""
    problems: List[Tuple[str, str]]
    """Every (key, message)."""

class Scenario:
    @staticmethod
    def resolve(name: str) -> Scenario: ...
    @staticmethod
    def builtin(name: str) -> Scenario: ...
    @staticmethod
    def from_toml(text: str, source: str = "<string>") -> Scenario: ...
    @staticmethod
    def from_path(path: str) -> Scenario: ...
    def with_options(self, options: Dict[str, Any]) -> Scenario: ...
    def to_toml(self) -> str: ...
    def warnings(self) -> List[str]: ...
    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def source(self) -> str: ...
    @property
    def model(self) -> str: ...
    @property
    def nodes(self) -> int: ...
    @property
    def links(self) -> int: ...
    @property
    def steps(self) -> int: ...
    @property
    def duration_s(self) -> float: ...
    @property
    def rate_hz(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def estimators(self) -> List[str]: ...
    @property
    def digest(self) -> str: ...
    def positions(self, t: float = ...) -> List[Tuple[int, float, float, float]]: ...

Progress = Optional[Callable[[int, int], Any]]

def run(scenario: Scenario, progress: Progress = None, tables: bool = True) -> Dict[str, Any]:
    """{summary: str (summary.json), links: bytes (CSV), trace, measurements, estimators: bytes | None (CSV),
    keyboard_interrupt: bool}"""

def sweep(
    scenario: Scenario,
    axes: Sequence[str],
    out: Union[str, PathLike[str]],
    seeds: int = 10,
    estimators: Union[str, Sequence[str], None] = None,
    rounds: Optional[int] = None,
    duration: Optional[float] = None,
    transport: str = "memory",
    progress: Progress = None,
) -> Dict[str, Any]:
    """{dir, runs, ran, kept, stopped, failed: [(key, point, seed, why)], files, keyboard_interrupt}"""

def bounds(
    lams: Sequence[float],
    a: Optional[List[List[float]]] = None,
    c: Optional[List[List[float]]] = None,
    q: Optional[List[List[float]]] = None,
    r: Optional[List[List[float]]] = None,
    scenario: Optional[Scenario] = None,
    measure: bool = False,
) -> Dict[str, Any]:
    """{rho, lambda_min, lambda_bar, lambda_bar_interval, rows: [(λ, trace S̄, trace V̄, S̄, V̄, measured)]}"""

def attitude(
    file: str,
    reference: Optional[str] = None,
    columns: Optional[str] = None,
    units: Optional[str] = None,
    rate: Optional[float] = None,
    gates: Optional[str] = None,
    calibrate_mag: bool = False,
    compare: List[Tuple[str, str]] = [],
) -> Dict[str, Any]:
    """{json: the text simnet attitude --json prints, csv: attitude.csv as bytes}"""

def builtins() -> List[Tuple[str, str]]: ...
def estimators() -> List[Tuple[str, str, str, str]]: ...
def version() -> str: ...
