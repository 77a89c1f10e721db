"""pyuff on the other side of frfbayes' UFF reader and writer (tests/uff_pyuff.rs).

    python3 pyuff_io.py write <frfs.json> <out.uff> <binary 0|1>
        Writes every function of frfs.json with pyuff (dataset 58 ASCII or 58b).
    python3 pyuff_io.py read <in.uff> <out.json>
        Reads every dataset 58 of in.uff with pyuff and dumps what it read.
    python3 pyuff_io.py mat <frfs.json> <out.mat>
        The FRFs (function type 4) of frfs.json as a MATLAB file (scipy.io.savemat):
        freq_hz (1 x n), frf (n x responses, complex), coherence (n x responses, from
        the type-6 functions in the same order).

frfs.json: {"functions": [{"func_type", "rsp_node", "rsp_dir", "ref_node", "ref_dir",
"rsp_ent_name", "x": [...], "re": [...], "im": [...] or null, "ordinate_units",
"denominator_units", "ordinate_type", "denominator_type", "id1"}]}
"""
import json
import os
import sys

import numpy as np
import pyuff


def write(src, dst, binary):
    with open(src) as fh:
        spec = json.load(fh)
    if os.path.exists(dst):
        os.remove(dst)
    uff = pyuff.UFF(dst)
    for f in spec["functions"]:
        re = np.asarray(f["re"], dtype=float)
        data = re if f["im"] is None else re + 1j * np.asarray(f["im"], dtype=float)
        dset = pyuff.prepare_58(
            binary=binary,
            func_type=f["func_type"],
            rsp_node=f["rsp_node"],
            rsp_dir=f["rsp_dir"],
            ref_node=f["ref_node"],
            ref_dir=f["ref_dir"],
            rsp_ent_name=f["rsp_ent_name"],
            ref_ent_name="NONE",
            data=data,
            x=np.asarray(f["x"], dtype=float),
            id1=f["id1"],
            abscissa_spacing=1,
            abscissa_spec_data_type=18,
            abscissa_axis_units_lab="Hz",
            ordinate_spec_data_type=f["ordinate_type"],
            ordinate_axis_units_lab=f["ordinate_units"],
            orddenom_spec_data_type=f["denominator_type"],
            orddenom_axis_units_lab=f["denominator_units"],
        )
        uff.write_sets(dset, mode="add")


def read(src, dst):
    sets = pyuff.UFF(src).read_sets()
    if isinstance(sets, dict):
        sets = [sets]
    out = []
    for s in sets:
        if s["type"] != 58:
            continue
        d = np.asarray(s["data"])
        out.append({
            "func_type": int(s["func_type"]),
            "rsp_node": int(s["rsp_node"]),
            "rsp_dir": int(s["rsp_dir"]),
            "ref_node": int(s["ref_node"]),
            "ref_dir": int(s["ref_dir"]),
            "binary": int(s.get("binary", 0)),
            "x": [float(v) for v in s["x"]],
            "re": [float(v) for v in d.real],
            "im": [float(v) for v in d.imag] if np.iscomplexobj(d) else None,
            "ordinate_units": s.get("ordinate_axis_units_lab", "").strip(),
        })
    with open(dst, "w") as fh:
        json.dump({"functions": out}, fh)


def mat(src, dst):
    import scipy.io
    with open(src) as fh:
        spec = json.load(fh)
    frfs = [f for f in spec["functions"] if f["func_type"] == 4]
    cohs = [f for f in spec["functions"] if f["func_type"] == 6]
    frf = np.column_stack([np.asarray(f["re"]) + 1j * np.asarray(f["im"]) for f in frfs])
    coh = np.column_stack([np.asarray(f["re"]) for f in cohs])
    scipy.io.savemat(dst, {"freq_hz": np.asarray(frfs[0]["x"])[None, :], "frf": frf, "coherence": coh})


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    elif sys.argv[1] == "mat":
        mat(sys.argv[2], sys.argv[3])
    elif sys.argv[1] == "read":
        read(sys.argv[2], sys.argv[3])
    else:
        sys.exit("usage: pyuff_io.py write|read ...")
