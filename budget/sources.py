"""The source documents' bibliographic citations, by seed document (docs/references.md):
what the claims page (:mod:`budget.runner.claims_page`) heads each paper's table with."""

from __future__ import annotations

__all__ = ["CITATIONS", "citation"]

#: seed document -> (short name, full citation); docs/references.md
CITATIONS = {
    "000": ("Wang et al. 2018",
            "Wang Weizhi, Wang Yan, Yu Yanbo, Di Jingjing, Zong Yunhua, Gao Weijun, \u201cAccuracy determination "
            "for sub-arcsec star camera\u201d, Infrared and Laser Engineering 47(9), 0917002 (2018), "
            "doi:10.3788/IRLA201847.0917002"),
    "001": ("Dong et al. 2019",
            "Dong Hao, Sun Tuo, Wu Li'na, Tang Shuai, Liu Xiaobo, \u201cAn angular error compensation technology "
            "for airborne infrared spectral camera\u201d, Infrared and Laser Engineering 48(10), 1013007 (2019), "
            "doi:10.3788/IRLA201948.1013007"),
    "002": ("Miao et al.",
            "Miao Zhuang, He Bin, Wang Junqi, Chen Qixing, Yang Xiaojie, whiskbroom TDICCD space camera: "
            "image-motion velocity model and Monte Carlo error synthesis (journal version of Z. Miao's "
            "master thesis, 2016)"),
    "003": ("Jia, Xu & Chen 2012",
            "Jia Yinghong, Xu Shijie, Chen Tong, \u201cImaging position error compensation of scan mirror for "
            "spacecraft\u201d, Journal of Beijing University of Aeronautics and Astronautics 38(2), 153-159 "
            "(2012)"),
    "004": ("Guan et al. 2022",
            "Guan Zhichao, Li Zhen, Jiang Yonghua, Zhang Guo, Shen Xin, Chinese patent \u201cStar-observation "
            "mode on-board geometric calibration method for a linear-array camera\u201d (2022)"),
}


def citation(seed_document: str) -> tuple[str, str]:
    """``(short name, full citation)`` of ``seed_document`` (a plain label if unknown)."""
    return CITATIONS.get(seed_document, (f"seed {seed_document}", f"source document {seed_document}"))
