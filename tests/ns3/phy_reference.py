"""ns-3 lr-wpan's own numbers for simnet's radio arithmetic (`simnet_core::medium::phy`), written as JSON for the
integration test `ns3::the_radio_arithmetic_is_ns3s` to compare against.

    python3 tests/ns3/phy_reference.py target/ns3/phy.json

Needs `pip install ns3==3.44.post0` (ns-3 with lr-wpan, driven through cppyy)."""

import json
import os
import sys

from ns import ns


def main(path):
    out = {"ns3": "3.44"}
    model = ns.CreateObject[ns.lrwpan.LrWpanErrorModel]()
    # Success rate of a chunk of `bits` bits at an SNR, on a quarter-dB grid from -10 to +7 dB.
    out["success"] = [
        [snr_db, bits, model.GetChunkSuccessRate(10 ** (snr_db / 10), bits)]
        for snr_db in [x / 4 for x in range(-40, 29)]
        for bits in [1, 160, 248, 1016]
    ]
    loss = ns.CreateObject[ns.LogDistancePropagationLossModel]()
    a = ns.CreateObject[ns.ConstantPositionMobilityModel]()
    b = ns.CreateObject[ns.ConstantPositionMobilityModel]()
    a.SetPosition(ns.Vector(0, 0, 0))
    rows = []
    for d in [0.5, 1.0, 2.0, 10.0, 50.0, 95.0, 150.0, 300.0]:
        b.SetPosition(ns.Vector(d, 0, 0))
        rows.append([d, -loss.CalcRxPower(0.0, a, b)])
    out["log_distance_loss_db"] = rows
    # The noise a receiver of maximum sensitivity (noise factor 1) integrates over channel 11.
    helper = ns.lrwpan.LrWpanSpectrumValueHelper()
    psd = helper.CreateNoisePowerSpectralDensity(11)
    out["noise_w"] = ns.lrwpan.LrWpanSpectrumValueHelper.TotalAvgPower(psd, 11)
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
    print(f"wrote {path}: {len(out['success'])} success rates, {len(rows)} path losses, noise {out['noise_w']:.6e} W")


if __name__ == "__main__":
    main(sys.argv[1])
