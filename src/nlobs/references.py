"""The one table of the works nlobs implements or relies on.

Everything a user reads (certificates, the report, the CLI, the README, the docs) cites a work
through :func:`cite` (short form, "Yi, Ortega & Zhang (2019), Proposition 1") and lists it
through :func:`full_citation`; code comments and tests may cite the papers' text files by name
and equation number (the ``file`` field links the two).

Bibliographic data comes from the texts themselves where they give it. Where a text gives no
venue or year, the entry says where the data comes from (``source``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["Reference", "REFERENCES", "work", "cite", "full_citation", "cited_keys", "bibliography"]


@dataclass(frozen=True)
class Reference:
    """One work: who, what, where, when.

    Attributes
    ----------
    key : str
        Short key used in the code (``"004"`` for a paper of the catalogue, ``"sedoglavic2002"``...).
    authors : str
        Authors as printed ("B. Yi, R. Ortega, W. Zhang").
    short : str
        Surnames for the short citation ("Yi, Ortega & Zhang").
    title : str
    venue : str
        Journal, proceedings or report series, with volume and pages when known.
    year : int
    file : str
        The text file in the papers folder (only for the five papers of the catalogue).
    doi : str
    source : str
        Where the venue/year come from when the text itself does not give them.
    """

    key: str
    authors: str
    short: str
    title: str
    venue: str
    year: int
    file: str = ""
    doi: str = ""
    source: str = ""

    @property
    def label(self) -> str:
        """The short citation, "Surname, Surname & Surname (year)"."""
        return f"{self.short} ({self.year})"

    def __str__(self) -> str:
        return full_citation(self.key)


_ALL = (
    # -- the five papers of the catalogue --------------------------------------------------------
    Reference("000", "L. Wang, R. Ortega, A. Bobtsov", "Wang, Ortega & Bobtsov",
              "Observability is sufficient for the design of globally exponentially convergent state observers "
              "for state-affine nonlinear systems", "arXiv:2108.09406", 2021, file="000_6cd8bea7ca1db43b.txt",
              source="the text gives no venue or year; arXiv record 2108.09406"),
    Reference("001", "D. Viegas, P. Batista, P. Oliveira, C. Silvestre", "Viegas, Batista, Oliveira & Silvestre",
              "Nonlinear observability and observer design through state augmentation",
              "Proc. 54th IEEE Conference on Decision and Control (CDC)", 2015, file="001_1b4027b3a70d560f.txt",
              source="the text gives no venue or year (its newest reference is from 2014); CDC 2015 proceedings"),
    Reference("002", "G. Besançon", "Besançon", "On observability & observer forms",
              "lecture slides, Mines ParisTech / GIPSA-lab, 1 March 2010 (see also G. Besançon, "
              "Nonlinear observers and applications, Springer, 2007)", 2010, file="002_613af42269ea26a7.txt"),
    Reference("003", "S. P. Banks", "Banks", "A note on nonlinear observers",
              "Research Report ACSE 126, Dept. of Control Engineering, University of Sheffield", 1980,
              file="003_a2c72ccb4281ea3f.txt"),
    Reference("004", "B. Yi, R. Ortega, W. Zhang", "Yi, Ortega & Zhang",
              "On state observers for nonlinear systems: a new design and a unifying framework",
              "IEEE Transactions on Automatic Control 64(3):1193–1200", 2019, file="004_f1e237c45ff4719e.txt",
              doi="10.1109/TAC.2018.2839526"),
    # -- works the papers point to, and the algorithms nlobs uses beyond them ----------------------
    Reference("sedoglavic2002", "A. Sedoglavic", "Sedoglavic",
              "A probabilistic algorithm to test local algebraic observability in polynomial time",
              "Journal of Symbolic Computation 33(5):735–755", 2002),
    Reference("aranovskiy2017", "S. Aranovskiy, A. Bobtsov, R. Ortega, A. Pyrkin", "Aranovskiy, Bobtsov, Ortega & Pyrkin",
              "Performance enhancement of parameter estimators via dynamic regressor extension and mixing",
              "IEEE Transactions on Automatic Control 62(7):3546–3550", 2017),
    Reference("andrieu2006", "V. Andrieu, L. Praly", "Andrieu & Praly",
              "On the existence of a Kazantzis–Kravaris/Luenberger observer",
              "SIAM Journal on Control and Optimization 45(2):432–456", 2006),
    Reference("kalman1961", "R. E. Kalman, R. S. Bucy", "Kalman & Bucy", "New results in linear filtering and prediction theory",
              "Journal of Basic Engineering 83(1):95–108", 1961),
    Reference("julier2004", "S. J. Julier, J. K. Uhlmann", "Julier & Uhlmann", "Unscented filtering and nonlinear estimation",
              "Proceedings of the IEEE 92(3):401–422", 2004),
    Reference("thau1973", "F. E. Thau", "Thau", "Observing the state of non-linear dynamic systems",
              "International Journal of Control 17(3):471–479", 1973),
    Reference("gauthier1992", "J.-P. Gauthier, H. Hammouri, S. Othman", "Gauthier, Hammouri & Othman",
              "A simple observer for nonlinear systems: applications to bioreactors",
              "IEEE Transactions on Automatic Control 37(6):875–880", 1992),
    Reference("hong2019", "H. Hong, A. Ovchinnikov, G. Pogudin, C. Yap", "Hong, Ovchinnikov, Pogudin & Yap",
              "SIAN: software for structural identifiability analysis of ODE models", "Bioinformatics 35(16):2873–2874", 2019),
    Reference("hong2020", "H. Hong, A. Ovchinnikov, G. Pogudin, C. Yap", "Hong, Ovchinnikov, Pogudin & Yap",
              "Global identifiability of differential models", "Communications on Pure and Applied Mathematics "
              "73(9):1831–1879", 2020, doi="10.1002/cpa.21921"),
    Reference("berthomieu2021", "J. Berthomieu, C. Eder, M. Safey El Din", "Berthomieu, Eder & Safey El Din",
              "msolve: a library for solving polynomial systems", "Proc. ISSAC 2021, 51–58", 2021,
              doi="10.1145/3452143.3465545"),
    Reference("dong2023", "R. Dong, C. Goodbrake, H. A. Harrington, G. Pogudin", "Dong, Goodbrake, Harrington & Pogudin",
              "Differential elimination for dynamical models via projections with applications to structural "
              "identifiability", "SIAM Journal on Applied Algebra and Geometry 7(1):194–235", 2023,
              doi="10.1137/22M1469067"),
    Reference("ovchinnikov2023", "A. Ovchinnikov, G. Pogudin, P. Thompson", "Ovchinnikov, Pogudin & Thompson",
              "Input-output equations and identifiability of ODE models",
              "IEEE Transactions on Automatic Control 68(2):812–824", 2023, doi="10.1109/TAC.2022.3145571"),
    Reference("ovchinnikov2021", "A. Ovchinnikov, A. Pillay, G. Pogudin, T. Scanlon", "Ovchinnikov, Pillay, Pogudin & Scanlon",
              "Multi-experiment parameter identifiability of ODEs and model theory",
              "SIAM Journal on Applied Algebra and Geometry 6(3):339–367", 2022, doi="10.1137/21M1389845"),
    Reference("schoukens2016", "M. Schoukens, P. Mattsson, T. Wigren, J.-P. Noël", "Schoukens, Mattsson, Wigren & Noël",
              "Cascaded tanks benchmark combining soft and hard nonlinearities",
              "Workshop on Nonlinear System Identification Benchmarks, Brussels", 2016),
    # -- works cited in the prose of docstrings and certificates -----------------------------------
    Reference("jazwinski1970", "A. H. Jazwinski", "Jazwinski", "Stochastic Processes and Filtering Theory",
              "Academic Press, New York", 1970),
    Reference("bucy1968", "R. S. Bucy, P. D. Joseph", "Bucy & Joseph",
              "Filtering for Stochastic Processes with Applications to Guidance", "Interscience, New York", 1968),
    Reference("simon2006", "D. Simon", "Simon", "Optimal State Estimation: Kalman, H∞, and Nonlinear Approaches",
              "Wiley, Hoboken", 2006),
    Reference("sarkka2007", "S. Särkkä", "Särkkä",
              "On unscented Kalman filtering for state estimation of continuous-time nonlinear systems",
              "IEEE Transactions on Automatic Control 52(9):1631–1641", 2007),
    Reference("wan2000", "E. A. Wan, R. van der Merwe", "Wan & van der Merwe", "The unscented Kalman filter for nonlinear estimation",
              "Proc. IEEE Adaptive Systems for Signal Processing, Communications, and Control Symposium (AS-SPCC), 153–158", 2000),
    Reference("rauch1965", "H. E. Rauch, F. Tung, C. T. Striebel", "Rauch, Tung & Striebel",
              "Maximum likelihood estimates of linear dynamic systems", "AIAA Journal 3(8):1445–1450", 1965),
    Reference("sarkka2008", "S. Särkkä", "Särkkä", "Unscented Rauch–Tung–Striebel smoother",
              "IEEE Transactions on Automatic Control 53(3):845–849", 2008),
    Reference("sarkka2013", "S. Särkkä, J. Sarmavuori", "Särkkä & Sarmavuori",
              "Gaussian filtering and smoothing for continuous-discrete dynamic systems", "Signal Processing 93(2):500–510",
              2013),
    Reference("schweppe1965", "F. C. Schweppe", "Schweppe", "Evaluation of likelihood functions for Gaussian signals",
              "IEEE Transactions on Information Theory 11(1):61–70", 1965),
    Reference("barshalom2001", "Y. Bar-Shalom, X. R. Li, T. Kirubarajan", "Bar-Shalom, Li & Kirubarajan",
              "Estimation with Applications to Tracking and Navigation", "Wiley, New York", 2001),
    Reference("byrd1995", "R. H. Byrd, P. Lu, J. Nocedal, C. Zhu", "Byrd, Lu, Nocedal & Zhu",
              "A limited memory algorithm for bound constrained optimization", "SIAM Journal on Scientific Computing "
              "16(5):1190–1208", 1995, doi="10.1137/0916069"),
    Reference("harvey1989", "A. C. Harvey", "Harvey", "Forecasting, Structural Time Series Models and the Kalman Filter",
              "Cambridge University Press, Cambridge", 1989),
    Reference("tobin1958", "J. Tobin", "Tobin", "Estimation of relationships for limited dependent variables",
              "Econometrica 26(1):24–36", 1958, doi="10.2307/1907382"),
    Reference("allik2016", "B. Allik, C. Miller, M. J. Piovoso, R. Zurakowski", "Allik, Miller, Piovoso & Zurakowski",
              "The Tobit Kalman filter: an estimator for censored measurements",
              "IEEE Transactions on Control Systems Technology 24(1):365–371", 2016),
    Reference("chen1996", "C. Chen, O. L. Mangasarian", "Chen & Mangasarian",
              "A class of smoothing functions for nonlinear and mixed complementarity problems",
              "Computational Optimization and Applications 5(2):97–138", 1996),
    Reference("ljung1999", "L. Ljung", "Ljung", "System Identification: Theory for the User",
              "2nd ed., Prentice Hall, Upper Saddle River", 1999),
    Reference("byrd1999", "R. H. Byrd, M. E. Hribar, J. Nocedal", "Byrd, Hribar & Nocedal",
              "An interior point algorithm for large-scale nonlinear programming",
              "SIAM Journal on Optimization 9(4):877–900", 1999),
    Reference("vandermerwe2001", "R. van der Merwe, E. A. Wan", "van der Merwe & Wan",
              "The square-root unscented Kalman filter for state and parameter-estimation",
              "Proc. IEEE International Conference on Acoustics, Speech, and Signal Processing (ICASSP) 6:3461–3464", 2001),
    Reference("arasaratnam2009", "I. Arasaratnam, S. Haykin", "Arasaratnam & Haykin", "Cubature Kalman filters",
              "IEEE Transactions on Automatic Control 54(6):1254–1269", 2009),
    Reference("golub2013", "G. H. Golub, C. F. Van Loan", "Golub & Van Loan", "Matrix Computations",
              "4th ed., Johns Hopkins University Press, Baltimore", 2013),
    Reference("kaminski1971", "P. G. Kaminski, A. E. Bryson, S. F. Schmidt", "Kaminski, Bryson & Schmidt",
              "Discrete square root filtering: a survey of current techniques",
              "IEEE Transactions on Automatic Control 16(6):727–736", 1971),
    Reference("bell1993", "B. M. Bell, F. W. Cathey", "Bell & Cathey", "The iterated Kalman filter update as a Gauss-Newton method",
              "IEEE Transactions on Automatic Control 38(2):294–297", 1993),
    Reference("gordon1993", "N. J. Gordon, D. J. Salmond, A. F. M. Smith", "Gordon, Salmond & Smith",
              "Novel approach to nonlinear/non-Gaussian Bayesian state estimation", "IEE Proceedings F 140(2):107–113", 1993),
    Reference("pitt1999", "M. K. Pitt, N. Shephard", "Pitt & Shephard", "Filtering via simulation: auxiliary particle filters",
              "Journal of the American Statistical Association 94(446):590–599", 1999),
    Reference("kitagawa1996", "G. Kitagawa", "Kitagawa",
              "Monte Carlo filter and smoother for non-Gaussian nonlinear state space models",
              "Journal of Computational and Graphical Statistics 5(1):1–25", 1996),
    Reference("kong1994", "A. Kong, J. S. Liu, W. H. Wong", "Kong, Liu & Wong",
              "Sequential imputations and Bayesian missing data problems",
              "Journal of the American Statistical Association 89(425):278–288", 1994),
    Reference("rao2003", "C. V. Rao, J. B. Rawlings, D. Q. Mayne", "Rao, Rawlings & Mayne",
              "Constrained state estimation for nonlinear discrete-time systems: stability and moving horizon approximations",
              "IEEE Transactions on Automatic Control 48(2):246–258", 2003),
    Reference("ioannou1996", "P. A. Ioannou, J. Sun", "Ioannou & Sun", "Robust Adaptive Control", "Prentice Hall, Upper Saddle River", 1996),
    Reference("ljungbox1978", "G. M. Ljung, G. E. P. Box", "Ljung & Box", "On a measure of lack of fit in time series models",
              "Biometrika 65(2):297–303", 1978, doi="10.1093/biomet/65.2.297"),
    Reference("kuhl2011", "P. Kühl, M. Diehl, T. Kraus, J. P. Schlöder, H. G. Bock", "Kühl, Diehl, Kraus, Schlöder & Bock",
              "A real-time algorithm for moving horizon state and parameter estimation",
              "Computers & Chemical Engineering 35(1):71–83", 2011),
    Reference("simon2010", "D. Simon", "Simon", "Kalman filtering with state constraints: a survey of linear and nonlinear algorithms",
              "IET Control Theory & Applications 4(8):1303–1318", 2010),
    # -- sensor selection (nlobs sensors) -----------------------------------------------------------
    Reference("liu2013", "Y.-Y. Liu, J.-J. Slotine, A.-L. Barabási", "Liu, Slotine & Barabási",
              "Observability of complex systems", "Proceedings of the National Academy of Sciences 110(7):2460–2465", 2013,
              doi="10.1073/pnas.1215508110"),
    Reference("summers2016", "T. H. Summers, F. L. Cortesi, J. Lygeros", "Summers, Cortesi & Lygeros",
              "On submodularity and controllability in complex dynamical networks",
              "IEEE Transactions on Control of Network Systems 3(1):91–101", 2016, doi="10.1109/TCNS.2015.2453711"),
    Reference("krener2009", "A. J. Krener, K. Ide", "Krener & Ide", "Measures of unobservability",
              "Proc. 48th IEEE Conference on Decision and Control (CDC) held jointly with the 28th Chinese Control Conference, "
              "6401–6406", 2009, doi="10.1109/CDC.2009.5400067"),
    Reference("montanari2020", "A. N. Montanari, L. A. Aguirre", "Montanari & Aguirre",
              "Observability of network systems: a critical review of recent results",
              "Journal of Control, Automation and Electrical Systems 31:1348–1374", 2020, doi="10.1007/s40313-020-00633-5"),
    Reference("nemhauser1978", "G. L. Nemhauser, L. A. Wolsey, M. L. Fisher", "Nemhauser, Wolsey & Fisher",
              "An analysis of approximations for maximizing submodular set functions—I",
              "Mathematical Programming 14(1):265–294", 1978, doi="10.1007/BF01588971"),
    Reference("leskovec2007", "J. Leskovec, A. Krause, C. Guestrin, C. Faloutsos, J. VanBriesen, N. Glance",
              "Leskovec, Krause, Guestrin, Faloutsos, VanBriesen & Glance", "Cost-effective outbreak detection in networks",
              "Proc. 13th ACM SIGKDD International Conference on Knowledge Discovery and Data Mining, 420–429", 2007,
              doi="10.1145/1281192.1281239"),
    # -- sources of the bundled model library (nlobs models) --------------------------------------
    Reference("vanderpol1926", "B. van der Pol", "van der Pol", "On \u201crelaxation-oscillations\u201d",
              "The London, Edinburgh, and Dublin Philosophical Magazine and Journal of Science, Series 7, 2(11):978–992",
              1926),
    Reference("duffing1918", "G. Duffing", "Duffing",
              "Erzwungene Schwingungen bei veränderlicher Eigenfrequenz und ihre technische Bedeutung",
              "Friedr. Vieweg & Sohn, Braunschweig", 1918),
    Reference("lorenz1963", "E. N. Lorenz", "Lorenz", "Deterministic nonperiodic flow",
              "Journal of the Atmospheric Sciences 20(2):130–141", 1963),
    Reference("rossler1976", "O. E. Rössler", "Rössler", "An equation for continuous chaos",
              "Physics Letters A 57(5):397–398", 1976),
    Reference("lotka1925", "A. J. Lotka", "Lotka", "Elements of Physical Biology", "Williams & Wilkins, Baltimore", 1925),
    Reference("volterra1926", "V. Volterra", "Volterra", "Fluctuations in the abundance of a species considered mathematically",
              "Nature 118:558–560", 1926),
    Reference("kermack1927", "W. O. Kermack, A. G. McKendrick", "Kermack & McKendrick",
              "A contribution to the mathematical theory of epidemics",
              "Proceedings of the Royal Society of London A 115(772):700–721", 1927),
    Reference("hethcote2000", "H. W. Hethcote", "Hethcote", "The mathematics of infectious diseases",
              "SIAM Review 42(4):599–653", 2000),
    Reference("uppal1974", "A. Uppal, W. H. Ray, A. B. Poore", "Uppal, Ray & Poore",
              "On the dynamic behavior of continuous stirred tank reactors", "Chemical Engineering Science 29(4):967–985", 1974),
    Reference("bastin1990", "G. Bastin, D. Dochain", "Bastin & Dochain", "On-line Estimation and Adaptive Control of Bioreactors",
              "Elsevier, Amsterdam", 1990),
    Reference("thrun2005", "S. Thrun, W. Burgard, D. Fox", "Thrun, Burgard & Fox", "Probabilistic Robotics",
              "MIT Press, Cambridge, MA", 2005),
    Reference("messner1999", "W. C. Messner, D. M. Tilbury", "Messner & Tilbury",
              "Control Tutorials for MATLAB and Simulink: A Web-Based Approach", "Addison-Wesley, Reading, MA", 1999),
    Reference("astrom2008", "K. J. Åström, R. M. Murray", "Åström & Murray",
              "Feedback Systems: An Introduction for Scientists and Engineers", "Princeton University Press", 2008),
    Reference("fitzhugh1961", "R. FitzHugh", "FitzHugh", "Impulses and physiological states in theoretical models of nerve membrane",
              "Biophysical Journal 1(6):445–466", 1961),
    Reference("mahony2012", "R. Mahony, V. Kumar, P. Corke", "Mahony, Kumar & Corke",
              "Multirotor aerial vehicles: modeling, estimation, and control of quadrotor",
              "IEEE Robotics & Automation Magazine 19(3):20–32", 2012, doi="10.1109/MRA.2012.2206474"),
    Reference("groves2013", "P. D. Groves", "Groves",
              "Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems",
              "2nd ed., Artech House, Boston", 2013),
    Reference("sola2017", "J. Solà", "Solà", "Quaternion kinematics for the error-state Kalman filter",
              "arXiv:1711.02508", 2017),
)

#: Every work nlobs cites, by key.
REFERENCES = MappingProxyType({r.key: r for r in _ALL})


def _get(key: str) -> Reference:
    try:
        return REFERENCES[key]
    except KeyError:
        raise KeyError(f"no reference {key!r}; known: {', '.join(REFERENCES)}") from None


def work(key: str, where: str = "") -> tuple[str, str]:
    """A work (its key, checked now) and a place in it, as an observer kind declares what it implements.

    >>> work("004", "Proposition 1")
    ('004', 'Proposition 1')
    """
    _get(key)
    return key, where


def cite(key: str, where: str = "") -> str:
    """The short citation of `key`, optionally followed by a place in the work.

    >>> cite("004", "Proposition 1")
    'Yi, Ortega & Zhang (2019), Proposition 1'
    """
    label = _get(key).label
    return f"{label}, {where}" if where else label


def full_citation(key: str) -> str:
    """The full reference: authors, "title", venue, year (and DOI).

    >>> full_citation("003")
    'S. P. Banks, "A note on nonlinear observers", Research Report ACSE 126, Dept. of Control Engineering, University of Sheffield, 1980.'
    """
    r = _get(key)
    text = f'{r.authors}, "{r.title}", {r.venue}, {r.year}'
    return text + (f", doi:{r.doi}." if r.doi else ".")


def cited_keys(text: str) -> list[str]:
    """The keys of the works a text cites through :func:`cite`, in order of first appearance."""
    found = []
    for r in _ALL:
        m = re.search(re.escape(r.label), text)
        if m:
            found.append((m.start(), r.key))
    return [k for _, k in sorted(found)]


def bibliography(*texts: str) -> list[str]:
    """Full citations of every work cited in `texts`, in order of first appearance."""
    joined = "\n".join(texts)
    return [full_citation(k) for k in cited_keys(joined)]
