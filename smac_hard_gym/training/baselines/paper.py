"""The SMAC-HARD paper's numbers that the sweep's report sets beside ours (arXiv 2412.17707, SMAC-HARD; SC2 with
pymarl2 QMIX and MAPPO, 5 seeds, 32 test episodes): (QMIX, MAPPO) per map, copied from the tables named in
:data:`SOURCES`, and the paper's map order (:data:`MAP_ORDER`), which the tables and reports follow."""

from __future__ import annotations

__all__ = ["PAPER", "SOURCES", "MAP_ORDER"]

MAP_ORDER = ("3m", "8m", "5m_vs_6m", "8m_vs_9m", "10m_vs_11m", "25m", "27m_vs_30m", "2s3z", "3s5z", "3s5z_vs_3s6z",
              "1c3s5z", "3s_vs_3z", "3s_vs_4z", "3s_vs_5z", "bane_vs_bane", "so_many_baneling", "2s_vs_1sc",
              "2m_vs_1z", "2c_vs_64zg", "MMM", "MMM2", "6h_vs_8z", "corridor")


def _table(*pairs: tuple[float, float]) -> dict[str, tuple[float, float]]:
    return dict(zip(MAP_ORDER, pairs, strict=True))


PAPER: dict[str, dict[str, tuple[float, float]]] = {
    # Appendix A, "Final performance at 2M time step with default opponent policy" (SMACv1's opponent).
    "smac_2m": _table(
        (0.9798, 0.9897), (0.9797, 0.9538), (0.544, 0.5103), (0.9137, 0.7821), (0.9515, 0.6859), (0.975, 0.9692),
        (0.4202, 0.6051), (0.9732, 0.941), (0.9485, 0.4512), (0.0256, 0.1128), (0.9893, 0.982), (0.994, 0.982),
        (0.9857, 0.9744), (0.7771, 0.9744), (0.783, 0.9974), (0.9672, 0.9821), (0.9917, 1.0), (0.9926, 1.0),
        (0.9226, 0.9359), (0.9824, 0.9256), (0.7875, 0.4487), (0.1438, 0.0154), (0.0, 0.3077)),
    # Section 6.1, Table "Performance in SMAC-HARD tasks within 10M time steps" (the mixed pool).
    "default_10m": _table(
        (0.9938, 1.0), (0.9628, 0.6438), (0.4375, 0.3138), (0.4938, 0.3528), (0.6813, 0.5681), (0.7813, 0.4562),
        (0.0313, 0.0938), (0.4125, 0.8735), (0.3625, 0.7225), (0.0, 0.1569), (0.9625, 0.5445), (0.9913, 0.9875),
        (0.7938, 0.9875), (0.3438, 0.9407), (0.975, 0.9125), (0.9625, 0.8813), (0.7563, 0.8375), (0.0, 0.0),
        (0.7891, 0.9741), (0.9875, 0.3267), (0.275, 0.1925), (0.0188, 0.0607), (0.3063, 0.1804)),
    # Appendix A, "Final performance at 2M time step with mixed edited opponent policy".
    "default_2m": _table(
        (0.9917, 0.6166), (0.8083, 0.5979), (0.3166, 0.3104), (0.4063, 0.2958), (0.3646, 0.3813), (0.5313, 0.2583),
        (0.0, 0.0125), (0.3438, 0.7042), (0.2312, 0.0667), (0.0, 0.0), (0.4708, 0.5292), (0.8771, 0.9979),
        (0.4437, 0.95), (0.2125, 0.7479), (0.9646, 0.8813), (0.9375, 0.7896), (0.0167, 0.5604), (0.0, 0.0),
        (0.0958, 0.6542), (0.8167, 0.25), (0.0, 0.0), (0.0, 0.0125), (0.0, 0.0)),
    # Section 6.2, Table "Performance in SMAC-HARD tasks in black-box mode" (trained 10M steps on SMACv1).
    "blackbox_10m": _table(
        (0.0117, 0.1028), (0.0375, 0.0513), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0),
        (0.0508, 0.1217), (0.0313, 0.0375), (0.0, 0.0), (0.0703, 0.1027), (0.3359, 0.4125), (0.7461, 0.4467),
        (0.5305, 0.5359), (0.2578, 0.3484), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.6238, 0.3419), (0.0, 0.0),
        (0.0, 0.0), (0.0898, 0.0), (0.0, 0.0)),
}


SOURCES = {
    "smac_2m": "paper, appendix A, table 'Final performance at 2M time step with default opponent policy'",
    "default_10m": "paper, section 6.1, table 'Performance in SMAC-HARD tasks within 10M time steps'",
    "default_2m": "paper, appendix A, table 'Final performance at 2M time step with mixed edited opponent policy'",
    "blackbox_10m": "paper, section 6.2, table 'Performance in SMAC-HARD tasks in black-box mode'",
}
