#!/usr/bin/env python
"""The IFToMM A05 stiff flyball governor in Exudyn (pip install exudyn; 1.13.6 used), an independent reference for mbdk's
scene (python/mbdk/scenes/spatial/): Exudyn's generalized-alpha index-3 solver with fixed steps,
converged by halving h (second order; tests/test_spatial.py quotes the values of h = 1.25e-4
(Bricard) and 6.25e-5 (flyball), Richardson-extrapolated, which agree with mbdk's to a few 1e-9).
Adapted from Exudyn's own examples (main/pythonDev/TestModels/bricardMechanism.py,
main/pythonDev/Examples/stiffFlyballGovernorKT.py). Not a test: it runs only where exudyn is
installed.

usage: python benchmarks/exudyn_flyball.py h [rho] [t_end] [newton_tol] [solver]
"""
import sys, json, time
import numpy as np
import exudyn as exu
from exudyn.utilities import *

h    = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-3
rho  = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
tEnd = float(sys.argv[3]) if len(sys.argv) > 3 else 2.0
tol  = float(sys.argv[4]) if len(sys.argv) > 4 else 1e-10
solver = sys.argv[5] if len(sys.argv) > 5 else 'GeneralizedAlpha'

SC = exu.SystemContainer()
mbs = SC.AddSystem()

lengthShaft = 1.; widthShaft = 0.01
lengthRod = 1.;   widthRod = 0.01
dimSlider = 0.1;  sSlider = 0.5
xAB = 0.1; beta0 = np.deg2rad(30)
omega0 = 2*np.pi
mShaft = 0.3; mRod = 0.3; mSlider = 3.; mMassPoint = 5.
g = [0, 0, -9.81]
k = 8e5; c = 4e4; l0 = 0.5

iShaft  = InertiaCuboid(density=mShaft/(widthShaft**2*lengthShaft), sideLengths=[widthShaft, widthShaft, lengthShaft])
iSlider = InertiaCuboid(density=mSlider/dimSlider**3, sideLengths=[dimSlider]*3)   # 0.005 about each axis
iRod    = InertiaCuboid(density=mRod/(lengthRod*widthRod**2), sideLengths=[lengthRod, widthRod, widthRod]).Translated([lengthRod/2, 0, 0])
iMass   = InertiaMassPoint(mass=mMassPoint).Translated([lengthRod, 0, 0])
iRodSum = iRod + iMass   # point mass lumped into rod (rigidly attached at rod end: exact)
inertiaList = [iShaft, iSlider, iRodSum, iRodSum]

# links: 0 shaft (RevoluteZ, frame at (0,0,0.5)), 1 slider (PrismaticZ rel. shaft), 2/3 rods (RevoluteY rel. shaft at z=1)
nq = 4
nGeneric = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.]*nq, initialCoordinates=[0.]*nq,
                                       initialCoordinates_t=[omega0, 0, 0, 0], numberOfODE2Coordinates=nq))
refPosList = [[0, 0, lengthShaft*0.5], [0, 0, sSlider-lengthShaft*0.5],
              [xAB/2, 0, lengthShaft*0.5], [-xAB/2, 0, lengthShaft*0.5]]
jointTypes = [exu.JointType.RevoluteZ, exu.JointType.PrismaticZ, exu.JointType.RevoluteY, exu.JointType.RevoluteY]
linkMasses = []; linkCOMs = exu.Vector3DList(); linkInertiasCOM = exu.Matrix3DList()
jointTransformations = exu.Matrix3DList(); jointOffsets = exu.Vector3DList()
for i in range(nq):
    inertia = inertiaList[i]
    linkMasses += [inertia.Mass()]
    linkCOMs.Append(inertia.COM())
    linkInertiasCOM.Append(inertia.InertiaCOM())
    A = np.eye(3)
    if i == 2: A = RotationMatrixY(beta0)         # rod A: local x = (cos30, 0, -sin30)
    if i == 3: A = RotationMatrixY(np.pi-beta0)   # rod B: local x = (-cos30, 0, -sin30)
    jointTransformations.Append(A)
    jointOffsets.Append(refPosList[i])

oKT = mbs.AddObject(ObjectKinematicTree(nodeNumber=nGeneric, jointTypes=jointTypes, linkParents=[-1, 0, 0, 0],
                                        jointTransformations=jointTransformations, jointOffsets=jointOffsets,
                                        linkInertiasCOM=linkInertiasCOM, linkCOMs=linkCOMs, linkMasses=linkMasses,
                                        baseOffset=[0., 0., 0.], gravity=g))

mRodA = mbs.AddMarker(MarkerKinematicTreeRigid(objectNumber=oKT, linkNumber=2, localPosition=[lengthRod/2, 0, 0]))
mSlE  = mbs.AddMarker(MarkerKinematicTreeRigid(objectNumber=oKT, linkNumber=1, localPosition=[dimSlider/2, 0, 0]))
mRodB = mbs.AddMarker(MarkerKinematicTreeRigid(objectNumber=oKT, linkNumber=3, localPosition=[lengthRod/2, 0, 0]))
mSlF  = mbs.AddMarker(MarkerKinematicTreeRigid(objectNumber=oKT, linkNumber=1, localPosition=[-dimSlider/2, 0, 0]))
mbs.AddObject(SpringDamper(markerNumbers=[mSlE, mRodA], stiffness=k, damping=c, referenceLength=l0))
mbs.AddObject(SpringDamper(markerNumbers=[mSlF, mRodB], stiffness=k, damping=c, referenceLength=l0))

sPos = mbs.AddSensor(SensorKinematicTree(objectNumber=oKT, linkNumber=1, localPosition=[0, 0, 0], storeInternal=True,
                                         outputVariableType=exu.OutputVariableType.Position))
sQ = mbs.AddSensor(SensorNode(nodeNumber=nGeneric, storeInternal=True, outputVariableType=exu.OutputVariableType.Coordinates))
sQt = mbs.AddSensor(SensorNode(nodeNumber=nGeneric, storeInternal=True, outputVariableType=exu.OutputVariableType.Coordinates_t))
mbs.Assemble()

ss = exu.SimulationSettings()
ss.timeIntegration.numberOfSteps = int(round(tEnd/h))
ss.timeIntegration.endTime = tEnd
ss.timeIntegration.verboseMode = 0
ss.solution.file.write = False
ss.solution.sensors.writePeriod = h
ss.timeIntegration.generalizedAlpha.spectralRadius = rho
ss.timeIntegration.generalizedAlpha.computeInitialAccelerations = True
ss.timeIntegration.newton.useModifiedNewton = False
ss.timeIntegration.newton.relativeTolerance = tol
ss.timeIntegration.newton.absoluteTolerance = tol*1e-2
ss.timeIntegration.adaptiveStep = False

t0 = time.time()
mbs.SolveDynamic(ss, solverType=getattr(exu.DynamicSolverType, solver))
cpu = time.time() - t0

P = mbs.GetSensorStoredData(sPos); t = P[:, 0]
Q = mbs.GetSensorStoredData(sQ)
def at(tq, arr):
    i = np.argmin(abs(t - tq)); assert abs(t[i]-tq) < 0.5*h, (tq, t[i])
    return arr[i]
out = {'solver': solver, 'h': h, 'rho': rho, 'tol': tol, 'cpu': cpu,
       's': {str(tq): float(at(tq, P[:, 3])) for tq in [0.1, 0.3, 0.5, 1.0, 2.0] if tq <= tEnd + 1e-12},
       'q_end': Q[-1, 1:].tolist()}
print(json.dumps(out))
import os
os.makedirs(os.path.join(os.path.dirname(os.path.abspath(__file__)), 'out'), exist_ok=True)
np.save(os.path.join(os.path.dirname(os.path.abspath(__file__)), 'out',
                     'flyball_%s_h%g_rho%g.npy' % (solver, h, rho)), np.column_stack([t, P[:, 1:4], Q[:, 1:]]))
