#!/usr/bin/env python
"""The IFToMM A04 Bricard mechanism in Exudyn (pip install exudyn; 1.13.6 used), an independent reference for mbdk's
scene (python/mbdk/scenes/spatial/): Exudyn's generalized-alpha index-3 solver with fixed steps,
converged by halving h (second order; tests/test_spatial.py quotes the values of h = 1.25e-4
(Bricard) and 6.25e-5 (flyball), Richardson-extrapolated, which agree with mbdk's to a few 1e-9).
Adapted from Exudyn's own examples (main/pythonDev/TestModels/bricardMechanism.py,
main/pythonDev/Examples/stiffFlyballGovernorKT.py). Not a test: it runs only where exudyn is
installed.

usage: python benchmarks/exudyn_bricard.py h [rho] [t_end] [newton_tol] [solver]
"""
import sys, json
import numpy as np
import exudyn as exu
from exudyn.utilities import *

h    = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-3
rho  = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
tEnd = float(sys.argv[3]) if len(sys.argv) > 3 else 10.0
tol  = float(sys.argv[4]) if len(sys.argv) > 4 else 1e-10
solver = sys.argv[5] if len(sys.argv) > 5 else 'GeneralizedAlpha'  # or TrapezoidalIndex2

SC = exu.SystemContainer()
mbs = SC.AddSystem()

L = 1.; r = 0.1; m = 1.; g = 9.81
inertia = InertiaCuboid(density=m/(L*r*r), sideLengths=[L, r, r])  # about COM
Icom = np.array(inertia.InertiaCOM())
inertia = inertia.Translated([0.5*L, 0, 0])  # body reference point = rod start

listP = [[0,0,0], [L,0,0], [L,-L,0], [L,-L,L], [0,-L,L], [0,0,L]]      # A,B,C,D,E,F
rotList = [np.eye(3), RotationMatrixZ(-0.5*pi), RotationMatrixY(-0.5*pi),
           RotationMatrixZ(pi), RotationMatrixZ(0.5*pi)]  # local x along rod 1..5
listRotAxes = [[0,1,0], [0,0,1], [1,0,0], [0,1,0], [0,0,1], [1,0,0]]

oGround = mbs.AddObject(ObjectGround())
listBodies = [oGround]
rods = []
for i, p in enumerate(listP):
    if i != 5:
        b0 = mbs.CreateRigidBody(inertia=inertia, referencePosition=p,
                                 referenceRotationMatrix=rotList[i],
                                 gravity=[0, -g, 0])
        rods.append(b0)
    else:
        b0 = oGround
    if i != 5:
        mbs.CreateRevoluteJoint(itemNumbers=[listBodies[-1], b0], position=p,
                                axis=listRotAxes[i], axisRadius=r, axisLength=1.1*r)
    else:
        # closing joint F (rod5-ground, axis x): generic joint, rotation about x free;
        # redundancy (one of 30 constraints) handled by dense solver with ignoreSingularJacobian
        mbs.CreateGenericJoint(itemNumbers=[listBodies[-1], b0], position=p,
                               constrainedAxes=[1,1,1, 0,1,1], axesRadius=r, axesLength=1.1*r)
    listBodies.append(b0)

# sensors: P3 = far end of rod2 (local [L,0,0]); COM pos/vel and local angular velocity for energy
sP3 = mbs.AddSensor(SensorBody(bodyNumber=rods[1], localPosition=[L,0,0], storeInternal=True,
                               outputVariableType=exu.OutputVariableType.Position))
sE = []
for b in rods:
    sE.append([mbs.AddSensor(SensorBody(bodyNumber=b, localPosition=[0.5*L,0,0], storeInternal=True,
                                        outputVariableType=ov))
               for ov in [exu.OutputVariableType.Position, exu.OutputVariableType.Velocity,
                          exu.OutputVariableType.AngularVelocityLocal]])
mbs.Assemble()

ss = exu.SimulationSettings()
ss.timeIntegration.numberOfSteps = int(round(tEnd/h))
ss.timeIntegration.endTime = tEnd
ss.timeIntegration.verboseMode = 0
ss.solution.file.write = False
ss.solution.sensors.writePeriod = h
ss.timeIntegration.generalizedAlpha.spectralRadius = rho   # rho=1: trapezoidal (Newmark 1/4,1/2), index 3
ss.timeIntegration.generalizedAlpha.computeInitialAccelerations = True
ss.timeIntegration.newton.useModifiedNewton = False
ss.timeIntegration.newton.relativeTolerance = tol
ss.timeIntegration.newton.absoluteTolerance = tol*1e-2
ss.timeIntegration.adaptiveStep = False
ss.linearSolver.solverType = exu.LinearSolverType.EigenDense
ss.linearSolver.ignoreSingularJacobian = True

dof = mbs.ComputeSystemDegreeOfFreedom(verbose=False)
import time; t0 = time.time()
mbs.SolveDynamic(ss, solverType=getattr(exu.DynamicSolverType, solver))
cpu = time.time() - t0

P3 = mbs.GetSensorStoredData(sP3)
t = P3[:, 0]
def at(tq):
    i = np.argmin(abs(t - tq)); assert abs(t[i]-tq) < 0.5*h, (tq, t[i])
    return P3[i, 1:4]

E = np.zeros(len(t))
for b, (sp, sv, sw) in zip(rods, sE):
    pos = mbs.GetSensorStoredData(sp)[:, 1:4]
    vel = mbs.GetSensorStoredData(sv)[:, 1:4]
    w = mbs.GetSensorStoredData(sw)[:, 1:4]
    E += 0.5*m*np.sum(vel**2, axis=1) + 0.5*np.einsum('ij,jk,ik->i', w, Icom, w) + m*g*pos[:, 1]
dE = E - E[0]
out = {'solver': solver, 'h': h, 'rho': rho, 'tol': tol, 'cpu': cpu, 'dof': {k: int(v) if np.isscalar(v) else None for k, v in dof.items()},
       'E0': E[0], 'maxAbsDrift': float(np.max(abs(dE))), 'driftEnd': float(dE[-1]),
       'P3': {str(tq): at(tq).tolist() for tq in [0.5, 1.0, 1.5, 2.0, 5.0, 10.0] if tq <= tEnd + 1e-12}}
print(json.dumps(out))
import os
os.makedirs(os.path.join(os.path.dirname(os.path.abspath(__file__)), 'out'), exist_ok=True)
np.save(os.path.join(os.path.dirname(os.path.abspath(__file__)), 'out',
                     'bricard_%s_h%g_rho%g.npy' % (solver, h, rho)), np.column_stack([t, P3[:, 1:4], E]))
