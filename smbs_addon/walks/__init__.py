"""The manifold walks (MNEE, SMS, SMBS): the walk from a seed to a solution (walk; its compiled
loop in kernels/walk.py, the Newton step in kernels/newton.py, the large mutation in
kernels/large_mutation.py), seeds (seeds), the estimator (estimators: unbiased Bernoulli trials or
biased unique solutions), what a solution contributes (contribution), the Bernoulli trials (trials),
the photon pre-pass that steers the walks (guide) and the manifold pass over a chunk of receivers
(manifold). constraints.py and large_mutation.py are numpy forms of the compiled physics that the
tests use as oracles. Imports the layers below.
"""
