"""Radial distance to contact along the whisker shaft (thesis Ch.4).

Contact features (CP, CA, DV, DA, AV, AA, WL; Sec 4.1.2.4) are mapped to the
radial distance from the whisker base to the contact point by scikit-learn
regressors (SVR, polynomial, MLP; Sec 4.1.3, Table 4.1), evaluated against the
tip assumption and a uniform-random baseline with the normalised radial error
of Eq 4.1, and plugged into forward kinematics to place contact points.

Modules
-------
``errors``       typed errors of this subpackage
``features``     feature names, units and the validated feature table
``datasets``     the three seeded simulated data sets (training rod, Box validation, Evans-style)
``models``       the Table 4.1 models and the two baselines as scikit-learn estimators
``evaluation``   Eq 4.1 errors, point-to-mesh distances, KS tests, PCA, Evans and Fig 4.11 studies
``persistence``  save/load with skops and a trusted-types list, feature and version checks
``pipeline``     radial-distance model + forward kinematics -> contact points
``plots``        PCA loadings, error histograms and box plots (matplotlib imported lazily)
"""
