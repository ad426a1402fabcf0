"""The model: the system's parameters and what is known of it in closed form.

Layer 0 (the bottom): imports nothing of pendsweep but :mod:`pendsweep.errors`.

* :mod:`.params`: Table IV's parameters, one declaration of every parameter
  (units, ranges, the kernel array), the paper's named parameter sets;
* :mod:`.analytic`: closed-form results (linear natural frequencies,
  the oscillator's response);
* :mod:`.loop`: the substructured test's loop designs, pure numbers: delay,
  forward prediction, the force filter.
"""
