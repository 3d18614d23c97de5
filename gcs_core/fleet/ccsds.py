"""The calibrated attitude history out as a CCSDS Attitude Ephemeris Message, through the
``ccsds-ndm`` library (docs/fleet.md).

:func:`write_aem` writes an ASF solution as an AEM 2.0 (CCSDS 504.0-B-2) in the NDM/XML
form (CCSDS 505.0-B-3); :func:`read_aem` reads one back through the library. GCS's
quaternion ``q = (q1, q2, q3, q4)``, scalar last, is the attitude matrix ``C_BI`` from GCI
(J2000 axes) to the body (ICD §2, Eq 4-8); it is written as ``Q1, Q2, Q3, QC`` with
``REF_FRAME_A = EME2000``, ``REF_FRAME_B = SC_BODY_1`` (the rotation from frame A to frame
B), ``TIME_SYSTEM = UTC``. Epochs carry 12 decimals of a second, so a time comes back within
1e-12 s plus its float rounding. (The OEM side is :mod:`gcs_core.io.ccsds`.)
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.io.ccsds import ndm_library, seconds_since, utc_text

__all__ = ["write_aem", "read_aem"]


def write_aem(
    path: str | Path,
    t: np.ndarray,
    q: np.ndarray,
    epoch: datetime,
    *,
    object_name: str,
    object_id: str | None = None,
    comments: tuple[str, ...] = (),
) -> Path:
    """Write the attitude history ``(t, q)`` as an AEM 2.0 in NDM/XML (module docstring).

    Parameters
    ----------
    t : (N,) s since ``epoch``, increasing; q : (N, 4) scalar-last GCI-to-body quaternions.
    epoch : the mission epoch (UTC). object_name, object_id : the spacecraft.
    comments : COMMENT lines (provenance: SCDS version, config hash...).
    """
    from ccsds_ndm.models.ndmxml4 import ndmxml_4_0_0_aem_2_0 as aem
    from ccsds_ndm.models.ndmxml4 import ndmxml_4_0_0_common_4_0 as common
    from ccsds_ndm.models.ndmxml4 import ndmxml_4_0_0_master_4_0 as master

    from gcs_core.fileperm import write_atomic

    NdmIo, NDMFileFormats = ndm_library()
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if t.size == 0 or q.shape != (t.size, 4):
        raise InputError(f"an AEM needs N ≥ 1 times and (N, 4) quaternions, not {t.shape} and {q.shape}")
    stamps = [utc_text(epoch, x) for x in t]
    states = [
        common.AttitudeStateType(
            quaternion_ephemeris=common.QuaternionEphemerisType(
                epoch=s, quaternion=common.QuaternionType(q1=float(a), q2=float(b), q3=float(c), qc=float(d))
            )
        )
        for s, (a, b, c, d) in zip(stamps, q)
    ]
    meta = aem.AemMetadata(
        comment=["q: C_BI, GCI (J2000 axes) to body, GCS ICD section 2; QC is the scalar part"],
        object_name=object_name,
        object_id=object_id or object_name,
        center_name="EARTH",
        ref_frame_a="EME2000",
        ref_frame_b="SC_BODY_1",
        time_system="UTC",
        start_time=stamps[0],
        stop_time=stamps[-1],
        attitude_type=common.AttitudeTypeType.QUATERNION,
    )
    seg = aem.AemSegment(metadata=meta, data=aem.AemData(comment=list(comments), attitude_state=states))
    header = common.AdmHeader(creation_date=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S"), originator="GCS")
    msg = master.Aem(header=header, body=aem.AemBody(segment=[seg]))
    text = NdmIo().to_string(msg, NDMFileFormats.XML)
    return write_atomic(Path(path), text, parents=True)


def read_aem(path: str | Path, epoch: datetime) -> tuple[np.ndarray, np.ndarray]:
    """(t [s since ``epoch``], q (N, 4) scalar last) of every segment of an AEM, through the
    library."""
    NdmIo, _ = ndm_library()
    msg = NdmIo().from_path(Path(path))
    t, q = [], []
    for seg in msg.body.segment:
        for st in seg.data.attitude_state:
            qe = st.quaternion_ephemeris
            if qe is None:
                raise InputError("only quaternion AEMs are read", file=path)
            qq = qe.quaternion
            t.append(seconds_since(epoch, qe.epoch, file=path))
            q.append((qq.q1, qq.q2, qq.q3, qq.qc))
    return np.array(t), np.array(q, dtype=float).reshape(-1, 4)
