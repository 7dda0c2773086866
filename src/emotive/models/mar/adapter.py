"""MAR style transfer behind the model contract (:mod:`emotive.models.api`).

Registered as ``mar`` (:mod:`emotive.models.registry`), a
:class:`~emotive.models.api.TransferModel` doing what ``emotive transfer`` does: the database
index is opened (the default one under ``$EMOTIVE_HOME/mar/`` is built from the Bandai Namco
data on first use, a few minutes) and
:func:`~emotive.models.mar.transfer.transfer_motion` translates the clip frame by frame into a
style, a blend or a schedule of styles.

Weights: the index file (``weights`` or the ``index`` option). Options: ``rho``,
``input_style``, ``action`` and ``roles`` (the input rig's role map), as for
:func:`~emotive.models.mar.transfer.transfer_motion`.

Legend: ``T`` frames, ``C`` labels, ``S`` the index's styles.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console

from emotive.models.api import Generated
from emotive.models.mar.config import MARConfig, TransferError
from emotive.models.mar.database import MARDatabase
from emotive.models.mar.default_index import build_default_index, default_index_path
from emotive.models.mar.transfer import transfer_motion

if TYPE_CHECKING:
    from emotive.core.motion import Motion
    from emotive.data.emotion import EmotionSchedule
    from emotive.models.mar.database import MARDatabase


def open_index(index: str | Path | None = None, progress: bool = True) -> MARDatabase:
    """The index at ``index``, or the default one (built first when missing).

    Raises:
        TransferError: a given index file that does not exist.
    """
    config = MARConfig()
    if index is not None:
        path = Path(index)
        if not path.is_file():
            raise TransferError(f"style-transfer index {path} does not exist: build it with "
                                "`emotive transfer --build-index --index PATH`, or leave it out "
                                "for the default index")
        return MARDatabase.load(path)
    path = default_index_path(config)
    if not path.is_file():
        if progress:
            Console(stderr=True).print(
                f"building the style-transfer index {path} from {', '.join(config.datasets)} "
                "(once; a few minutes)")
        build_default_index(config, path, progress=progress)
    return MARDatabase.load(path)


@dataclass
class MARTransfer:
    """An opened MAR index as a :class:`~emotive.models.api.TransferModel`.

    Attributes:
        db: the database index.
        name: its name in reports.
        rho: content kept for inputs unlike the data (``None``: the default 0.7).
        input_style: the input's style, if known.
        action: the input's action, if known.
        roles: role map of the input rig.
    """

    db: MARDatabase
    name: str = "mar"
    rho: float | None = None
    input_style: str | None = None
    action: str | None = None
    roles: Any = None

    @property
    def labels(self) -> tuple[str, ...]:
        """The styles of the index."""
        return self.db.styles

    def transfer(self, motion: Motion, style: EmotionSchedule, progress: bool = False
                 ) -> Generated:
        """``motion`` in ``style`` (see :meth:`emotive.models.api.TransferModel.transfer`).

        Returns:
            The output on the input's rig at its frame rate and the ``(T, C)`` style weights
            per output frame over ``style``'s labels.

        Raises:
            EmotionError: weight on a style the index has no clips of.
            TransferError: a clip shorter than the search window, or NaN frames.
            RigMappingError: the input rig lacks joint roles.
        """
        spec: Any = style.relabel(self.db.styles)
        if len(spec.times) == 1:
            spec = dict(zip(spec.labels, spec.weights[0].tolist(), strict=True))
        status = (Console(stderr=True).status(f"translating {motion.num_frames} frames ...")
                  if progress else nullcontext())
        with status:
            result = transfer_motion(motion, self.db, spec, action=self.action,
                                     input_style=self.input_style, rho=self.rho,
                                     role_map=self.roles)
        out = result.motion
        emotion = style.sample(out.fps, num_frames=out.num_frames)
        return Generated(out, emotion, tuple(style.labels), None,
                         f"{out.num_frames} frames ({out.duration:.2f} s) in style "
                         f"{out.metadata.get('style', '')}; feet "
                         f"{'pinned' if result.pinned else 'not pinned (no contacts)'}")


def load_transfer(name: str = "mar", weights: str | Path | None = None,
                  index: str | Path | None = None, rho: float | None = None,
                  input_style: str | None = None, action: str | None = None,
                  roles: Any = None) -> MARTransfer:
    """Registry loader: the index of ``weights`` or ``index`` (default: built on first use).

    Raises:
        TransferError: both ``weights`` and ``index`` given and different, or a missing
            index file.
    """
    if weights is not None and index is not None and Path(weights) != Path(index):
        raise TransferError(f"give the index once: weights {weights} and index {index} differ")
    return MARTransfer(open_index(weights if weights is not None else index), name, rho,
                       input_style, action, roles)
