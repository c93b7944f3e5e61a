function dydt = testcode(t, y)
% TESTCODE  Right-hand side called by Code 01's "ode45('testcode',time,y0)".
%
% NOT PRINTED in the thesis: Code 01 calls a function 'testcode' and
% declares "global CC" (the 4 x 4 coefficient matrix [0 I; -inv(M)*K 0]),
% but the listing of testcode is not in the appendix. This is the
% reconstruction implied by the listing: dy/dt = CC*y. It is the only
% file here that is not a transcription.
%
% testcode_nfev counts the calls for run_code01_ode45.m (the driver sets it
% to 0; it is not part of the thesis' program).
global CC
global testcode_nfev
dydt = CC*y(:);
testcode_nfev = testcode_nfev + 1;
end
